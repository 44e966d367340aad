"""The stroke tuner's breaststroke timing parameters (studies/swim_tune_stroke.py).

The tuner retimes the breaststroke's legs by a piecewise-linear phase map through three
timing marks (the recovery's start, the kick's start, its end) and moves the phase at which
the legs close. A stroke's keys must stay in phase order (a key list out of order is another
stroke, or no stroke at all: the interpolation needs increasing phases), the cycle's ends
must stay put (phase 0 and 1 are the same instant of the cycle), and parameters at zero must
give the starting stroke back exactly (the first trial of a run is the starting stroke,
swum to the bit).
"""

from __future__ import annotations

import importlib.util
import itertools
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flapsim.swim.strokes import stroke_path

PATH = Path(__file__).resolve().parent.parent / "studies" / "swim_tune_stroke.py"


@pytest.fixture(scope="module")
def tuner():
    spec = importlib.util.spec_from_file_location("study_swim_tune_stroke", PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def raw():
    return tomllib.loads(stroke_path("breaststroke").read_text())


def test_the_leg_phase_map_keeps_order_and_ends(tuner):
    marks = [0.30, 0.60, 0.77]
    # every combination of large moves, including ones that would cross the marks over
    for shifts in itertools.product((-0.5, -0.12, 0.0, 0.12, 0.5), repeat=3):
        g, moved = tuner.leg_phase_map(marks, list(shifts))
        assert g(0.0) == 0.0 and g(1.0) == 1.0
        gaps = np.diff([0.0, *moved, 1.0])
        assert np.all(gaps >= tuner.LEG_GAP - 1e-12), (shifts, moved)
        ph = np.linspace(0.0, 1.0, 201)
        assert np.all(np.diff([g(p) for p in ph]) > 0.0), shifts
        # where the moved marks leave their gaps, every mark moves by its own shift
        want = [m + s for m, s in zip(marks, shifts, strict=True)]
        if np.all(np.diff([0.0, *want, 1.0]) >= tuner.LEG_GAP):
            assert moved == pytest.approx(want)


def test_zero_parameters_give_the_starting_stroke(tuner, raw):
    spec, _ = tuner.SPECS["breaststroke"]
    assert tuner.apply_params(raw, spec, np.zeros(len(spec))) == raw


@pytest.mark.parametrize("seed", range(5))
def test_tuned_breaststroke_keys_stay_in_order(tuner, raw, seed):
    spec, _ = tuner.SPECS["breaststroke"]
    x = np.random.default_rng(seed).uniform(-1.0, 1.0, len(spec))
    x[[i for i, s in enumerate(spec) if s[0] in ("legs", "phase")]] = \
        np.random.default_rng(seed + 100).choice([-1.0, 1.0], 5)
    out = tuner.apply_params(raw, spec, x)
    for joint, dofs in out["keys"].items():
        for dof, keys in dofs.items():
            ph = [k[0] for k in keys]
            assert np.all(np.diff(ph) > 0.0), (joint, dof, ph)
            assert 0.0 <= ph[0] and ph[-1] <= 1.0
    # the legs' keys at phase 0 are not moved (the cycle starts in the glide)
    for joint in tuner.LEG_JOINTS:
        for dof, keys in out["keys"][joint].items():
            assert keys[0][0] == raw["keys"][joint][dof][0][0] == 0.0
    # the arms are not retimed by the legs' marks
    assert [k[0] for k in out["keys"]["shoulder_l"]["flex"]] == \
        [k[0] for k in raw["keys"]["shoulder_l"]["flex"]]
