"""Your own creature: a quadruped, a biped and a snake written for these tests (straight
legs, joint names unlike the bundled creatures'), from load to gait, gait files, root
travel with planted feet, and the dynamic creature on a user's model."""

from __future__ import annotations

import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from flapsim.cli.main import main
from flapsim.core.errors import InputError
from flapsim.modal.animate import animate
from flapsim.modal.gaits import GAITS, plan_gait, resolve_model
from flapsim.modal.heuristics import HeuristicParams
from flapsim.modal.legs import find_legs, leg_straightness
from flapsim.modal.own import travel_root

DATA = Path(__file__).parent / "data"
QUAD = str(DATA / "quadruped.xml")
BIPED = str(DATA / "biped.xml")
SNAKE = str(DATA / "snake.xml")


def _animate(tmp_path, model, gait, *extra):
    out = tmp_path / f"{gait}.json"
    npz = tmp_path / f"{gait}.npz"
    # 1 s at 2 Hz = two whole cycles: the phase fit sees whole periods.
    assert main(["animate", model, "--gait", gait, "--seconds", "1", "--fps", "60",
                 "--npz", str(npz), "--json", str(out), *extra]) == 0
    return json.loads(out.read_text()), np.load(npz)


def _phases_from_npz(model_path, npz, feet):
    """Foot phases measured here from the trajectory alone: the time of each body-point's
    largest forward excursion relative to the root, from a brute-force search over a
    fine grid of phases (no least squares shared with the code under test)."""
    m = mujoco.MjModel.from_xml_path(model_path)
    d = mujoco.MjData(m)
    t = npz["times"]
    xs = np.zeros((len(t), len(feet)))
    for k, q in enumerate(npz["qpos"]):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        root = d.xpos[m.body("rear" if "quad" in model_path else "hips").id]
        for i, (b, local) in enumerate(feet):
            p = d.xpos[b] + d.xmat[b].reshape(3, 3) @ np.asarray(local)
            xs[k, i] = p[0] - root[0]
    grid = np.radians(np.arange(0.0, 360.0, 0.5))
    w = 2 * np.pi * 2.0
    out = []
    for i in range(len(feet)):
        x = xs[:, i] - xs[:, i].mean()
        corr = [float(x @ np.cos(w * t - g)) for g in grid]  # peaks when w t = g
        out.append(math.degrees(grid[int(np.argmax(corr))]))
    return out


def _diff(a, b):
    """Signed a - b wrapped to (-180, 180]."""
    return (a - b + 180.0) % 360.0 - 180.0


def _feet(model_path):
    m = mujoco.MjModel.from_xml_path(model_path)
    legs = find_legs(m, m.qpos_spring.copy())
    return [g.foot for g in legs.legs]


def test_legs_are_found_from_the_tree_and_straight_legs_detected():
    m = mujoco.MjModel.from_xml_path(QUAD)
    legs = find_legs(m, m.qpos_spring.copy())
    # The model's own layout: la/lb at x = -0.1 (hind), y = +-0.1; lc/ld front.
    assert [g.foot_name for g in legs.legs] == ["la_dn", "lb_dn", "lc_dn", "ld_dn"]
    assert [g.knee for g in legs.legs] == ["la_m", "lb_m", "lc_m", "ld_m"]
    assert legs.legs[0].hip == ("la_s", "la_o")
    # Flexion sign: +y hinges swing the lower leg's end backwards (y x -z = -x) for a
    # hind leg (+1); a front leg flexes the other way, as a dog's elbow (-1).
    assert [g.knee_sign for g in legs.legs] == [1.0, 1.0, -1.0, -1.0]
    # Straight vertical legs: a knee moves the point below it only fore-aft (0 exactly).
    assert leg_straightness(m, m.qpos_spring.copy(), legs) < 1e-12


def test_quadruped_trot_is_proposed_a_flexed_pose_and_pairs_diagonals(tmp_path):
    out, npz = _animate(tmp_path, QUAD, "trot")
    own = out["own_creature"]
    assert own["knee_flex_deg"] == 30.0 and "straight legs" in own["rest_pose"]
    assert own["stiffness_tuning"]["holds"] and own["stiffness_scale"] > 0
    hl, hr, fl, fr = _phases_from_npz(QUAD, npz, _feet(QUAD))
    # Trot: diagonal feet together (within 30 deg), lateral pairs half a cycle apart.
    assert abs(_diff(hl, fr)) < 30 and abs(_diff(hr, fl)) < 30
    assert abs(abs(_diff(hl, hr)) - 180) < 30 and abs(abs(_diff(fl, fr)) - 180) < 30
    # The JSON's phases (a least-squares fit) agree with this brute-force search to the
    # grid's 0.5 deg plus the fit's bias from the harmonics (a few degrees).
    js = out["foot_phase_deg"]
    assert abs(_diff(js["hind_left"], hl)) < 5 and abs(_diff(js["front_right"], fr)) < 5


def test_quadruped_amble_staggers_front_after_hind(tmp_path):
    out, npz = _animate(tmp_path, QUAD, "amble")
    hl, hr, fl, fr = _phases_from_npz(QUAD, npz, _feet(QUAD))
    # Amble: each front foot a quarter cycle after the hind foot of its side (90 +- 20).
    assert abs(_diff(fl, hl) - 90) < 20 and abs(_diff(fr, hr) - 90) < 20
    # On this model one mode tops both swings (B and G): the amble took the next best G
    # mode instead of collapsing into the trot.
    assert "G" in out["substituted"]
    modes = {c["mode"] for c in out["modes_used"]}
    assert len(modes) == 4


def test_a_gait_that_would_collapse_is_refused_with_the_reason():
    model = mujoco.MjModel.from_xml_path(QUAD)
    from flapsim.modal.own import prepare
    own = prepare(model, tune=False)
    # Demanding a substitute as strong as the top mode: none is, so the amble is refused.
    with pytest.raises(InputError, match="collapse into another"):
        plan_gait(model, GAITS["amble"], labels=own.labels,
                  params=HeuristicParams(min_substitute_relative=0.999))


def test_biped_walks_with_alternating_feet(tmp_path):
    out, npz = _animate(tmp_path, BIPED, "walk")
    assert out["own_creature"]["knee_flex_deg"] == 30.0
    left, right = _phases_from_npz(BIPED, npz, _feet(BIPED))
    assert abs(abs(_diff(left, right)) - 180) < 30
    cats = {k for c in out["modes_used"] for k in c["categories"]}
    assert {"A", "B"} <= cats


def test_straight_legs_kept_are_refused_with_the_real_cause(capsys):
    # Kept straight, the feet have no vertical motion: the refusal says so and how to fix
    # it (not that labels are missing: every label is there).
    assert main(["animate", QUAD, "--gait", "trot", "--flex-knees-deg", "0", "--no-tune",
                 "--seconds", "0.2"]) == 2
    err = capsys.readouterr().err
    assert "straight legs" in err and "flex the knees" in err and "labels" not in err


def test_save_gait_then_gait_file_reproduces_and_amplitude_changes_stride(tmp_path):
    gf = tmp_path / "amble.toml"
    a, npz_a = _animate(tmp_path, QUAD, "amble", "--save-gait", str(gf))
    b_json = tmp_path / "b.json"
    b_npz = tmp_path / "b.npz"
    assert main(["animate", QUAD, "--gait-file", str(gf), "--seconds", "1", "--fps", "60",
                 "--npz", str(b_npz), "--json", str(b_json)]) == 0
    np.testing.assert_allclose(np.load(b_npz)["qpos"], npz_a["qpos"], rtol=0, atol=1e-9)
    # Double the stride slider: the swing modes' amplitudes double, so each foot's
    # fore-aft excursion grows (by less than 2x: the knee modes are unchanged).
    text = gf.read_text().replace("stride = 1.0", "stride = 2.0")
    gf.write_text(text)
    c_json = tmp_path / "c.json"
    assert main(["animate", QUAD, "--gait-file", str(gf), "--seconds", "1", "--fps", "60",
                 "--json", str(c_json)]) == 0
    c = json.loads(c_json.read_text())
    for foot, s in a["stride_m"].items():
        assert 1.3 * s < c["stride_m"][foot] < 2.2 * s


@pytest.mark.parametrize("creature,gait_name", [("dog", "trot"), ("human", "walk")])
def test_root_travel_keeps_stance_feet_planted(creature, gait_name):
    model, _ = resolve_model(creature)
    plan = plan_gait(model, GAITS[gait_name])
    times = np.arange(120) / 120.0  # two cycles, finely sampled (slip hides between frames)
    anim = animate(model, plan.analysis.rest_qpos, plan.components, times)
    lab = plan.selection.labels
    tr = travel_root(model, anim.qpos, lab, plan.analysis.rest_qpos)
    # Measured here from the poses alone: every foot within 5 mm of the lowest is on the
    # ground; over each such stretch its horizontal drift from touchdown is its slip.
    d = mujoco.MjData(model)
    feet = lab.feet + (lab.front_feet or ())
    pos = np.zeros((len(times), len(feet), 3))
    for k, q in enumerate(tr.qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        for i, (b, local) in enumerate(feet):
            pos[k, i] = d.xpos[b] + d.xmat[b].reshape(3, 3) @ np.asarray(local)
    ground = pos[:, :, 2] - pos[:, :, 2].min(axis=1, keepdims=True) <= 0.005
    worst = 0.0
    for i in range(len(feet)):
        start = None
        for k in range(len(times)):
            if ground[k, i]:
                start = pos[k, i, :2] if start is None else start
                worst = max(worst, float(np.linalg.norm(pos[k, i, :2] - start)))
            else:
                start = None
    assert worst <= 0.02  # the acceptance bound: 2 cm per step
    # ... and the creature travels forward, at least one stride in two cycles.
    root = [d for d in range(model.njnt) if model.jnt_type[d] == 0][0]
    adr = model.jnt_qposadr[root]
    assert tr.qpos[-1, adr] - tr.qpos[0, adr] > 0.3


def test_creature_on_a_users_snake_moves_it_and_names_its_file(tmp_path):
    out = tmp_path / "s.json"
    still = tmp_path / "still.json"
    assert main(["creature", SNAKE, "--seconds", "1", "--no-progress", "--json", str(out)]) == 0
    assert main(["creature", SNAKE, "--seconds", "1", "--no-progress", "--amplitude-deg", "0",
                 "--json", str(still)]) == 0
    r, s = json.loads(out.read_text()), json.loads(still.read_text())
    assert Path(r["model_file"]) == Path(SNAKE).resolve()
    assert r["modes_driven"] == [6, 7]  # the two lowest vibrations (6 rigid modes first)
    # Driven, it goes at least a tenth of its length in 1 s; undriven, it stays put
    # (settling only): at least 20 times less.
    assert r["distance_horizontal_body_lengths"] > 0.1
    assert s["distance_horizontal_m"] < r["distance_horizontal_m"] / 20


def test_label_file_overrides_the_tree(tmp_path):
    m = mujoco.MjModel.from_xml_path(BIPED)
    f = tmp_path / "labels.toml"
    # Swap the sides on purpose and declare the right knee reversed: the file wins.
    f.write_text('[feet]\nleft = "q_sole"\nright = "p_sole"\n[knees]\nright = "-p_mid"\n')
    from flapsim.modal.legs import read_label_file
    legs = find_legs(m, m.qpos_spring.copy(), read_label_file(f))
    assert [g.foot_name for g in legs.legs] == ["q_sole", "p_sole"]
    assert legs.legs[1].knee == "p_mid" and legs.legs[1].knee_sign == -1.0
    assert legs.source["feet"] == "label file" and legs.source["knee left"] == "tree"
    f.write_text('[feet]\nleft = "no_such_part"\nright = "p_sole"\n')
    with pytest.raises(InputError, match="no_such_part"):
        find_legs(m, m.qpos_spring.copy(), read_label_file(f))


def test_stiffness_edits_change_the_modes_as_the_square_root(tmp_path):
    # Every joint x4 (no tuning): K -> 4K with M unchanged, so every natural frequency
    # doubles exactly (omega = sqrt(k/m)); the mode shapes and hence the gait stay.
    base, _ = _animate(tmp_path, BIPED, "walk", "--no-tune")
    m = mujoco.MjModel.from_xml_path(BIPED)
    edits = []
    for j in range(m.njnt):
        if m.jnt_stiffness[j] > 0:
            edits += ["--stiffness", f"{m.joint(j).name}=4"]
    stiff, _ = _animate(tmp_path, BIPED, "walk", "--no-tune", *edits)
    for a, b in zip(base["chosen"], stiff["chosen"], strict=True):
        assert a["mode"] == b["mode"]
        assert b["freq_hz_natural"] == pytest.approx(2 * a["freq_hz_natural"], rel=1e-9)


def test_posture_slider_offsets_along_the_knee_bend_mode(tmp_path):
    gf = tmp_path / "walk.toml"
    _, plain = _animate(tmp_path, BIPED, "walk", "--no-tune", "--save-gait", str(gf))
    gf.write_text(gf.read_text().replace("posture = 0.0", "posture = 0.1"))
    npz = tmp_path / "p.npz"
    assert main(["animate", BIPED, "--gait-file", str(gf), "--seconds", "1", "--fps", "60",
                 "--npz", str(npz)]) == 0
    m = mujoco.MjModel.from_xml_path(BIPED)
    knees = [m.jnt_qposadr[m.joint(n).id] for n in ("p_mid", "q_mid")]
    shift = (np.load(npz)["qpos"] - plain["qpos"])[:, knees].mean(axis=0)
    # Synchronous knee bend: both knees move the same way, by 0.1 x the shape's knee
    # entry (largest rotation 1 rad, so at most 0.1 rad; the soft limits are far away),
    # and posture > 0 crouches: these hinges turn about +y, so a positive angle swings
    # the shank's lower end backwards (y x -z = -x), i.e. flexes the knee.
    assert shift[0] == pytest.approx(shift[1], rel=1e-6)
    assert 0.005 < shift[0] <= 0.1 + 1e-9
