"""Behaviour no other test protected, each pinned against an independently derived number
(each checked to fail on a deliberate mutant of the code it protects)."""

import json
import math
import pathlib

import mujoco
import numpy as np
import pytest

from flapsim.core.callbacks import DISPATCHER
from flapsim.core.loading import load_model
from flapsim.fluid.flow import FlowField, Uniform
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces

ROOT = pathlib.Path(__file__).resolve().parents[2]

FREE_PLATE = """<mujoco><option gravity="0 0 0" timestep="0.001"/><worldbody>
  <body name="plate" pos="0 0 1"><freejoint/>
    <geom type="box" size=".1 .1 .001" mass=".1" contype="0" conaffinity="0"/></body>
  </worldbody></mujoco>"""


def test_friction_respects_the_free_surface_cut():
    # A vertical 0.2 m square (normal +x, forward +z: friction direction N x F = -y) in a
    # flow along y: the flow lies in the plate's plane and across F, so it makes friction
    # only, eta * A_wet * v (the swimming paper's friction term) with A_wet the submerged
    # area: the surface cut must scale friction exactly as it scales drag and lift.
    m = load_model(FREE_PLATE, is_xml=True)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    verts = np.array([[[0, -.1, -.1], [0, .1, -.1], [0, .1, .1], [0, -.1, .1]]])
    ps = PolygonSet.from_polygons(1, verts, forward=(0, 0, 1))
    eta, v, area = 2.0, 0.3, 0.04
    flow = FlowField([Uniform((0, v, 0))])

    def friction(surface_z):
        sf = SurfaceForces(m, ps, ["hoerner_plate"],
                           FluidParams(1000.0, friction=eta, surface_z=surface_z), flow)
        r = sf.evaluate(d)
        assert np.all(r.drag == 0) and np.all(r.lift == 0)
        return r.friction[0], r.submerged[0]

    full, frac = friction(None)
    assert frac == 1.0
    assert np.allclose(full, [0, eta * area * v, 0], rtol=1e-12)  # 0.024 N along the flow
    half, frac = friction(1.0)  # the surface through the plate's centre
    assert frac == pytest.approx(0.5, abs=1e-12)
    assert np.allclose(half, 0.5 * full, rtol=1e-12)
    part, frac = friction(1.05)
    assert 0.5 < frac < 1.0
    assert np.allclose(part, frac * full, rtol=1e-12)
    dry, frac = friction(0.8)  # the plate (z 0.9..1.1) entirely above the water
    assert frac == 0.0 and np.all(dry == 0)


def test_write_json_is_atomic(tmp_path, monkeypatch):
    from flapsim.core.io import write_json

    target = tmp_path / "r.json"
    write_json(target, {"v": 1})
    real = pathlib.Path.write_text

    def dies_halfway(self, text, *a, **k):
        real(self, text[: len(text) // 2], *a, **k)  # the process "dies" mid-write
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(pathlib.Path, "write_text", dies_halfway)
    with pytest.raises(OSError):
        write_json(target, {"v": 2, "long": list(range(100))})
    monkeypatch.undo()
    assert json.loads(target.read_text()) == {"v": 1}  # the old result, whole
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]  # no temporary left


def test_modal_damping_ratios_match_the_closed_form():
    # Two independent hinged point-like bodies: each is one mode with
    # omega = sqrt(k / I) and zeta = c / (2 sqrt(k I)) (a damped 1-DOF oscillator),
    # I = armature + 2/5 m r^2 for a sphere on an axis through its centre.
    xml = """<mujoco><worldbody>
      <body><joint name="a" axis="0 0 1" stiffness="4" damping="0.3" armature="0.01"/>
        <geom type="sphere" size=".1" mass="2"/></body>
      <body pos="1 0 0"><joint name="b" axis="0 0 1" stiffness="50" damping="0.05" armature="0.002"/>
        <geom type="sphere" size=".05" mass="1"/></body>
      </worldbody></mujoco>"""
    from flapsim.modal.analysis import analyze

    m = load_model(xml, is_xml=True)
    a = analyze(m)
    expect = {}
    for k, c, arm, mass, r in ((4.0, 0.3, 0.01, 2.0, 0.1), (50.0, 0.05, 0.002, 1.0, 0.05)):
        inertia = arm + 0.4 * mass * r * r
        expect[math.sqrt(k / inertia) / (2 * math.pi)] = c / (2 * math.sqrt(k * inertia))
    rows = sorted(a.table(), key=lambda r: r["freq_hz"])
    assert len(rows) == 2
    for row, (f, zeta) in zip(rows, sorted(expect.items()), strict=True):
        # eigen-solver round-off only
        assert row["freq_hz"] == pytest.approx(f, rel=1e-9)
        assert row["damping_ratio"] == pytest.approx(zeta, rel=1e-9)
        assert row["overdamped"] is False


@pytest.mark.parametrize("depth", [-0.3, -0.1, 0.0, 0.07, 0.2])
def test_compiled_linear_buoyancy_is_the_papers_formula(depth):
    # A sphere of radius R whose centre is `depth` above the water: the paper's linear
    # rule gives the submerged fraction (1 + d) / 2 with d = (level - z) / R, and the
    # compiled provider must push up with rho g V (1 + d) / 2 through qfrc_passive.
    from flapsim.fluid.buoyancy import Buoyancy, BuoyancyParams, EllipsoidSet

    R, rho, g = 0.2, 1000.0, 9.81
    m = load_model(f"""<mujoco><option gravity="0 0 -{g}"/><worldbody>
      <body pos="0 0 {depth}"><freejoint/><geom type="sphere" size="{R}" mass="1"/></body>
      </worldbody></mujoco>""", is_xml=True)
    d = mujoco.MjData(m)
    ell = EllipsoidSet(np.array([1]), np.zeros((1, 3)), np.eye(3)[None], np.full((1, 3), R))
    b = Buoyancy(m, ell, BuoyancyParams(water_level=0.0, fluid_density=rho, method="linear"))
    dd = float(np.clip(-depth / R, -1, 1))
    expected = rho * g * (4 / 3 * math.pi * R**3) * (1 + dd) / 2
    with b.register(d):
        mujoco.mj_forward(m, d)
        DISPATCHER.check(d)
        # free joint: qfrc_passive[2] is the world z force; vertical force at a point on
        # the vertical through the centre: no torque (round-off only)
        assert d.qfrc_passive[2] == pytest.approx(expected, rel=1e-12, abs=1e-9)
        assert np.allclose(d.qfrc_passive[[0, 1, 3, 4, 5]], 0, atol=1e-9)


def test_non_finite_forces_are_not_applied():
    m = load_model(FREE_PLATE, is_xml=True)
    d = mujoco.MjData(m)
    verts = np.array([[[-.1, -.1, 0], [.1, -.1, 0], [.1, .1, 0], [-.1, .1, 0]]])
    sf = SurfaceForces(m, PolygonSet.from_polygons(1, verts), ["flat_plate"], FluidParams(1.225),
                       FlowField([Uniform((2.0, 0, 0))]))
    from flapsim.core.errors import ProviderError

    with sf.register(d):
        mujoco.mj_forward(m, d)
        assert np.any(d.qfrc_passive != 0)  # a finite state gets its force
        d.qvel[3] = np.nan  # a NaN angular velocity: a NaN wrench
        mujoco.mj_forward(m, d)
        # nothing of it reaches MuJoCo (no springs or dampers in this model: exactly 0)
        assert np.all(np.isfinite(d.qfrc_passive)) and np.all(d.qfrc_passive == 0)
        with pytest.raises(ProviderError, match="non-finite"):
            DISPATCHER.check(d)


TIMINGS = {"wall_time_s", "wall_s", "analysis_s", "realtime_factor", "real_time_factor",
           "startup_s", "elapsed_s"}


def _without_timings(obj):
    if isinstance(obj, dict):
        return {k: _without_timings(v) for k, v in obj.items() if k not in TIMINGS}
    if isinstance(obj, list):
        return [_without_timings(v) for v in obj]
    return obj


@pytest.mark.parametrize("argv", [
    ["demo", "--seconds", "0.3"],
    ["modes", str(ROOT / "creatures" / "loop.xml"), "--count", "4"],
    ["animate", "--gait", "trot", "--seconds", "0.5"],
    ["swim", "--stroke", "treading", "--seconds", "0.5"],
])
def test_a_command_twice_gives_the_same_json(argv, tmp_path):
    from flapsim.cli import main as cli

    out = []
    for k in range(2):
        js = tmp_path / f"{k}.json"
        assert cli.main([*argv, "--json", str(js)]) == 0
        out.append(json.loads(js.read_text()))
    assert _without_timings(out[0]) == _without_timings(out[1])
    assert out[0].keys() == out[1].keys()


def test_a_parallel_sweep_equals_a_serial_one():
    from flapsim.swim.sweep import sweep

    values = [2.0, 0.5]  # lung volumes, L
    serial = sweep("treading", "lungs", values, seconds=0.6, workers=1)
    parallel = sweep("treading", "lungs", values, seconds=0.6, workers=2)
    assert [r["value"] for r in parallel] == values  # in the order asked, not as finished
    # floats bit for bit: the same simulation in another process
    assert _without_timings(parallel) == _without_timings(serial)
    assert serial[0]["com_height_mean_m"] != serial[1]["com_height_mean_m"]
