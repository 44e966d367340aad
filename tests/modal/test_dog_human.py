"""The dog (80 DOF), human (47 DOF) and cart scene of Kry et al. 2009, and stiffness tuning."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from flapsim.modal import analyze, fix_body_orientation
from flapsim.modal.gaits import resolve_model
from flapsim.modal.stiffness import TuningParams, sag, tune_stiffness


@pytest.fixture(scope="module")
def dog():
    return resolve_model("dog")[0]


@pytest.fixture(scope="module")
def human():
    return resolve_model("human")[0]


def _k(model, name):
    return float(model.jnt_stiffness[model.joint(name).id])


def test_dof_counts_match_the_paper(dog, human):
    # Paper Fig. 3: dog 80 DOF, human 47, human pushing a cart 42 (the closed loop
    # removes 6 of the 47 + 1 cart dofs), run with the head fixed 44.
    assert dog.nv == 80
    assert human.nv == 47
    cart = resolve_model("human_cart")[0]
    assert analyze(cart, keyframe="push").n_modes == 42
    head = analyze(human, keyframe="run", constraints=[fix_body_orientation("head")])
    assert head.n_modes == 44


def test_stiffness_as_in_the_paper(dog, human):
    # Fig. 3: dog 20 N m/rad with the spine x5; human 100 N m/rad with the spine x10.
    assert _k(dog, "knee_hl") == pytest.approx(20.0, rel=1e-12)
    assert _k(dog, "lumbar2_flex") == pytest.approx(100.0, rel=1e-12)
    assert _k(dog, "neck1_flex") == pytest.approx(100.0, rel=1e-12)
    assert _k(human, "knee_l") == pytest.approx(100.0, rel=1e-12)
    assert _k(human, "thorax_flex") == pytest.approx(1000.0, rel=1e-12)


def test_masses_come_from_geometry(dog, human):
    # Density 1000 kg/m^3 on the geoms: a medium dog ~30 kg and an adult ~67 kg; the
    # bounds are body-mass ranges of those animals, not fitted numbers.
    assert 15.0 < float(dog.body_mass.sum()) < 40.0
    assert 55.0 < float(human.body_mass.sum()) < 90.0
    # Every moving body has mass and a positive-definite inertia (from its geoms).
    assert np.all(dog.body_mass[1:] > 0) and np.all(dog.body_inertia[1:] > 0)


def test_labels_and_limits(dog, human):
    for m, sites, joints in (
        (dog, ("paw_hl", "paw_hr", "paw_fl", "paw_fr", "head"),
         ("knee_hl", "knee_hr", "elbow_fl", "elbow_fr")),
        (human, ("foot_l", "foot_r", "hand_l", "hand_r", "head"),
         ("knee_l", "knee_r", "elbow_l", "elbow_r")),
    ):
        for s in sites:
            assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, s) >= 0, s
        for j in joints:
            assert mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j) >= 0, j
        hinge = m.jnt_type == mujoco.mjtJoint.mjJNT_HINGE
        assert np.all(m.jnt_limited[hinge])  # every hinge has a range


def test_analysis_is_fast_and_has_low_modes(dog, human):
    # The paper: "a fraction of a second"; the lowest elastic modes sit in the range of
    # real gait frequencies (~1-2 Hz).
    for m in (dog, human):
        a = analyze(m)
        assert a.n_rigid == 6
        assert 0.5 < a.freqs_hz[6] < 2.0


def test_stiffness_tuning_finds_the_holding_threshold(human):
    # Sag must shrink as stiffness grows (the premise of bisection), and the tuned scale
    # must hold within the tolerance while a 10 % weaker one, by construction of the
    # bracket (rel_tol 0.1), does not.
    params = TuningParams(seconds=0.5, rel_tol=0.1)
    weak, _ = sag(human, 0.25, keyframe="run", seconds=0.5)
    strong, _ = sag(human, 4.0, keyframe="run", seconds=0.5)
    assert weak > strong
    res = tune_stiffness(human, keyframe="run", params=params)
    assert res.failing_scale < res.scale <= res.failing_scale * 1.1
    held, _ = sag(human, res.scale, keyframe="run", seconds=0.5)
    failed, _ = sag(human, res.failing_scale, keyframe="run", seconds=0.5)
    assert held <= math.radians(10.0) < failed
