"""Heuristics A-G pick the modes of the paper's Fig. 3 gaits; constraints in the basis."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from flapsim.modal.gaits import GAITS, plan_gait, resolve_model
from flapsim.modal.heuristics import score_modes


@pytest.fixture(scope="module")
def plans():
    out = {}
    for name, g in GAITS.items():
        model, _ = resolve_model(g.model)
        out[name] = (model, plan_gait(model, g))
    return out


def _by_cat(plan):
    return {c: entry for entry in plan.chosen for c in entry["categories"]}


@pytest.mark.parametrize("name", ["walk", "run", "run_head", "push_cart"])
def test_biped_locomotion_uses_swing_and_knee_in_quadrature(plans, name):
    # Section 4.3: a leg-swing mode (B) at 0 deg and an alternating knee mode (A) at
    # 90 deg, two different elastic modes.
    _, plan = plans[name]
    cats = _by_cat(plan)
    assert cats["B"]["mode"] != cats["A"]["mode"]
    assert cats["A"]["phase_deg"] - cats["B"]["phase_deg"] == 90
    assert min(cats["A"]["mode"], cats["B"]["mode"]) >= plan.analysis.n_rigid


def test_walk_swing_mode_is_the_papers_mode_6(plans):
    # Fig. 3's T-pose walk uses mode 6, the first elastic mode, as its swing.
    _, plan = plans["walk"]
    assert _by_cat(plan)["B"]["mode"] == 6


@pytest.mark.parametrize("name", ["trot", "amble"])
def test_quadruped_gaits_use_four_distinct_modes(plans, name):
    # Fig. 3: trot and amble each combine four modes: hind swing (B), front swing (G),
    # hind knee (A) and front-leg bend (F), with phases multiples of 90 deg.
    _, plan = plans[name]
    cats = _by_cat(plan)
    assert {"A", "B", "F", "G"} <= set(cats)
    assert len({cats[c]["mode"] for c in "ABFG"}) == 4
    assert all(cats[c]["phase_deg"] % 90 == 0 for c in "ABFG")


def test_trot_pairs_diagonals_and_amble_staggers_them(plans):
    trot, amble = _by_cat(plans["trot"][1]), _by_cat(plans["amble"][1])
    assert trot["G"]["phase_deg"] == trot["B"]["phase_deg"]  # front with hind swing
    assert trot["G"]["sign"] == -1  # ... of the opposite side: diagonal pairs
    assert amble["G"]["phase_deg"] - amble["B"]["phase_deg"] == 90  # four-beat


def test_jump_is_synchronous(plans):
    _, plan = plans["jump"]
    cats = _by_cat(plan)
    assert "bounce" in cats and "D" in cats and "E" in cats
    # Synchronous knees: the chosen D mode bends both knees the same way.
    model, _ = plans["jump"]
    shape = plan.analysis.shapes[:, cats["D"]["mode"]]
    kl = model.jnt_dofadr[model.joint("knee_l").id]
    kr = model.jnt_dofadr[model.joint("knee_r").id]
    assert shape[kl] * shape[kr] > 0
    assert abs(shape[kl] - shape[kr]) < 0.05 * abs(shape[kl])  # symmetric to 5 %


def test_rejected_modes_include_twists_and_jumping_jacks(plans):
    model, plan = plans["walk"]
    why = " ".join(plan.rejected().values())
    assert "twist" in why and "jumping jack" in why
    # The twist-rejected modes really roll/yaw the trunk more than they move the legs.
    sel = score_modes(plan.analysis, model)
    for s in sel.scores:
        if "twist" in sel.rejected.get(s.mode, ""):
            assert s.relative["twist"] >= max(s.relative[c] for c in "ABCDE")


def test_head_constrained_modes_keep_the_head_orientation(plans):
    # J_head R N u ~ 0 for every mode of the head-constrained run (to round-off: the
    # null space comes from an SVD, so ~1e-15 of the shape's size).
    model, plan = plans["run_head"]
    a = plan.analysis
    assert a.n_modes == 44
    d = mujoco.MjData(model)
    d.qpos[:] = a.rest_qpos
    mujoco.mj_forward(model, d)
    jr = np.zeros((3, model.nv))
    mujoco.mj_jacBody(model, d, None, jr, model.body("head").id)
    rel = np.linalg.norm(jr @ a.shapes, axis=0) / np.linalg.norm(a.shapes, axis=0)
    assert rel.max() < 1e-10
    # Without the constraint the same gait turns the head (so the check can fail).
    free = plan_gait(model, GAITS["run"])
    moved = max(np.linalg.norm(jr @ c.shape) for c in free.components)
    assert moved > 0.05


def test_cart_constrained_modes_keep_hands_on_handle(plans):
    # (J_hand - J_handle) R N u ~ 0 for both hands in every mode (first order).
    model, plan = plans["push_cart"]
    a = plan.analysis
    assert a.n_modes == 42
    d = mujoco.MjData(model)
    d.qpos[:] = a.rest_qpos
    mujoco.mj_forward(model, d)
    for side in "lr":
        jh, jc = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, d, jh, None, model.site(f"hand_{side}").id)
        mujoco.mj_jacSite(model, d, jc, None, model.site(f"handle_{side}").id)
        gap_rate = np.linalg.norm((jh - jc) @ a.shapes, axis=0)
        assert gap_rate.max() < 1e-10 * np.linalg.norm(a.shapes, axis=0).max()
        # The hands do move (with the cart): the loop is not frozen.
        assert np.linalg.norm(jh @ a.shapes, axis=0).max() > 0.01


def test_projection_closes_the_loop_at_finite_amplitude():
    from flapsim.modal.animate import ConstraintProjector, animate

    model, _ = resolve_model("human_cart")
    plan = plan_gait(model, GAITS["push_cart"])
    times = np.linspace(0.0, 0.5, 9)
    proj = ConstraintProjector(model, plan.analysis.rest_qpos, plan.constraints)
    anim = animate(model, plan.analysis.rest_qpos, plan.components, times, projector=proj)
    # Gauss-Newton from a ~mm first-order error converges quadratically: 1e-8 m is far
    # below anything visible and far above round-off.
    assert anim.constraint_residual < 1e-8


def test_missing_labels_are_one_line_errors(tmp_path):
    # A creature without labelled feet/knees cannot be scored; the CLI says which
    # labels to add and exits with status 2 (user error), writing nothing.
    from flapsim.cli.main import main

    path = tmp_path / "blob.xml"
    path.write_text("""<mujoco><worldbody><body pos="0 0 1"><freejoint/><geom size="0.1"/>
      <body pos="0 0 0.2"><joint name="j" axis="0 1 0" stiffness="5" range="-1 1"/>
      <geom size="0.05"/></body></body></worldbody></mujoco>""")
    out = tmp_path / "r.json"
    assert main(["animate", "--gait", "walk", "--model", str(path), "--json", str(out)]) == 2
    assert not out.exists()
