"""Wave-making resistance: one plate against the closed form, the towed swimmer against
people's wave drag (Toussaint et al. 2002) and its fading with depth (Vennell et al. 2006)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import InputError
from flapsim.fluid.flow import FlowField
from flapsim.fluid.surfaces import PolygonSet
from flapsim.fluid.waves import FR_HUMP, WaveDrag, WaveParams
from flapsim.swim.model import WAVE_C_HUMP, SwimmerParams
from flapsim.swim.tow import (
    TOUSSAINT_SPEED,
    TOUSSAINT_WAVE_N,
    calibrate_waves,
    tow,
    tow_forces,
)

PLATE = """<mujoco><option gravity="0 0 -9.81"/><worldbody><body><freejoint/>
<geom type="box" size="0.1 0.1 0.01"/></body></worldbody></mujoco>"""
RHO, L, C, G = 1000.0, 1.8, 0.01, 9.81


def _plate_force(depth: float, flow: tuple[float, float, float], normal=(0.0, 0.0, 1.0),
                 size: float = 0.1) -> np.ndarray:
    """Wave force [N] on one square plate (side ``size``) centred ``depth`` under the surface
    in a uniform ``flow``, the body at rest."""
    m = mujoco.MjModel.from_xml_string(PLATE)
    d = mujoco.MjData(m)
    d.qpos[2] = -depth
    n = np.asarray(normal, dtype=float)
    t = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
    t /= np.linalg.norm(t)
    s = np.cross(n, t)
    h = size / 2
    quad = np.array([h * (a * t + b * s) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    f = FlowField()
    f.set_uniform(flow)
    waves = WaveDrag(m, PolygonSet.from_polygons(1, quad[None], None, 0),
                     WaveParams(RHO, 0.0, L, C, G), f)
    mujoco.mj_forward(m, d)
    return waves.evaluate(d)[1][1]


def _closed_form(depth: float, v: float, area: float = 0.01) -> float:
    """1/2 rho C_w(Fr) A exp(-2 g d / v^2) v^2, C_w = C (Fr / 0.5)^4 below the hump."""
    fr = min(v / math.sqrt(G * L), FR_HUMP) / FR_HUMP
    return 0.5 * RHO * C * fr ** 4 * area * math.exp(-2.0 * G * depth / v ** 2) * v ** 2


def test_one_plate_meets_the_closed_form_against_its_motion():
    v = 1.5
    f = _plate_force(0.1, (0.0, -v, 0.0))
    # along the flow (against the plate's motion through the water), nothing vertical;
    # the same arithmetic, so only rounding differs
    assert f[0] == pytest.approx(0.0, abs=1e-12) and f[2] == 0.0
    assert f[1] == pytest.approx(-_closed_form(0.1, v), rel=1e-9)
    # a flow at 45 deg: the force turns with it, its size set by the speed alone
    g = _plate_force(0.1, (v / math.sqrt(2), v / math.sqrt(2), 0.0))
    assert np.linalg.norm(g) == pytest.approx(_closed_form(0.1, v), rel=1e-9)
    assert g[0] == pytest.approx(g[1], rel=1e-9)


def test_the_waves_fade_with_depth_as_the_square_of_a_kelvin_wave():
    v = 2.0
    k = G / v ** 2  # the Kelvin wave number [1/m]
    f1 = np.linalg.norm(_plate_force(0.2, (v, 0.0, 0.0)))
    f2 = np.linalg.norm(_plate_force(0.6, (v, 0.0, 0.0)))
    # resistance ~ amplitude^2 ~ exp(-2 k d): the ratio between two depths is closed form
    assert f2 / f1 == pytest.approx(math.exp(-2.0 * k * 0.4), rel=1e-9)
    # ten wavelengths' worth of decay under the surface: nothing left
    deep = np.linalg.norm(_plate_force(10.0 / k, (v, 0.0, 0.0)))
    assert deep < 1e-8 * f1
    # in still water there is no wave at all
    assert np.linalg.norm(_plate_force(0.1, (0.0, 0.0, 0.0))) == 0.0


def test_the_wave_force_is_continuous_through_the_surface_and_the_hump():
    v = 1.8
    # a vertical plate leaving the water: its wet fraction, and so its force, shrinks
    # smoothly to zero: its wet fraction runs over twice its circumradius (the engine's
    # rule, 0.14 m), so a 1 mm step moves at most 1/141 of the wet plate's force at the
    # surface (5 % for the decay's own change over the step)
    depths = np.linspace(0.08, -0.08, 161)
    f = np.array([_plate_force(z, (v, 0.0, 0.0), normal=(1.0, 0.0, 0.0))[0] for z in depths])
    assert f[-1] == 0.0 and f[0] > 0.0
    assert np.max(np.abs(np.diff(f))) <= 1.05 * _closed_form(0.0, v) * 0.001 / (0.1 * math.sqrt(2))
    # the Froude curve meets its plateau without a step (1e-6 m/s either side)
    v_hump = FR_HUMP * math.sqrt(G * L)
    lo = np.linalg.norm(_plate_force(0.01, (v_hump - 1e-6, 0.0, 0.0)))
    hi = np.linalg.norm(_plate_force(0.01, (v_hump + 1e-6, 0.0, 0.0)))
    assert hi == pytest.approx(lo, rel=1e-5)


def test_bad_wave_parameters_are_refused():
    with pytest.raises(InputError, match="c_hump"):
        WaveParams(c_hump=0.5)
    with pytest.raises(InputError, match="length"):
        WaveParams(length=0.0)
    with pytest.raises(InputError, match="wave_c_hump"):
        SwimmerParams(wave_c_hump=-1.0)


def test_the_calibration_point_is_people_s_wave_drag_at_speed():
    rounded = SwimmerParams(body_shape="rounded")
    # the stored coefficient is the fit rounded to 3 figures: 0.1 % apart at most
    assert calibrate_waves(rounded) == pytest.approx(WAVE_C_HUMP, rel=1e-3)
    hydro, waves = tow_forces([1.0, 1.5, TOUSSAINT_SPEED], rounded)
    # Toussaint et al. 2002: 11.5 N at 1.89 m/s (the rounding above: 0.1 %)
    assert waves[2] == pytest.approx(TOUSSAINT_WAVE_N, rel=2e-3)
    share = [w / (h + w) for h, w in zip(hydro, waves, strict=True)]
    # ... which was 12.1 % of their swimmers' active drag; here of the towed drag, a
    # person's within 6 % (test_tow), so the share within 2 points
    assert share[2] == pytest.approx(0.121, abs=0.02)
    # and negligible below 1.6 m/s: under a third of that share at 1.5 m/s, nothing at 1
    assert share[1] < 0.121 / 3 and share[0] < 0.005


def _brute_force_waves(sw_params: SwimmerParams, v: float, depth: float | None) -> float:
    """The wave drag summed in numpy over the polygons' world centroids (an implementation
    apart from the kernel's): the same streamlined body, the water streaming at ``v``."""
    from flapsim.swim.layers import BasicStrokeLayer
    from flapsim.swim.model import Swimmer, standing_height
    from flapsim.swim.strokes import parse_stroke
    from flapsim.swim.tow import STREAMLINE

    sw = Swimmer(sw_params)
    pose = BasicStrokeLayer(sw, parse_stroke(STREAMLINE, "<s>")).start_pose(0.0)
    sw.reset("prone", height=None if depth is None else -depth, qpos_joints=pose)
    pts = sw.hydro.world_centroids(sw.data)
    nz = sw.hydro.world_normals(sw.data)[:, 2]
    half = sw.polygons.extent * np.sqrt(np.clip(1.0 - nz ** 2, 0.0, None))
    wet = np.clip(0.5 - pts[:, 2] / (2.0 * np.maximum(half, 1e-300)), 0.0, 1.0)
    wet = np.where(half > 1e-12, wet, (pts[:, 2] < 0).astype(float))
    g = 9.81
    fr = min(v / math.sqrt(g * standing_height(sw.model)), FR_HUMP) / FR_HUMP
    decay = np.exp(-2.0 * g * np.maximum(0.0, -pts[:, 2]) / v ** 2)
    rho = sw_params.water_density
    return float(0.5 * rho * WAVE_C_HUMP * fr ** 4 * v ** 2 * (sw.polygons.area * wet * decay).sum())


def test_the_surface_tow_meets_more_drag_than_the_submerged_one_by_its_waves():
    p = SwimmerParams(body_shape="rounded")
    r = tow([2.0], p)
    surface, under = r.surface_n[0], r.submerged_n[0]
    expected = _brute_force_waves(p, 2.0, None) - _brute_force_waves(p, 2.0, 0.5)
    # the margin is the waves' (the surface engine's drag differs by the dry patches
    # alone: 0.1 N of ~98)
    assert surface - under == pytest.approx(expected, abs=1.0)
    assert (surface - under) / under > 0.10
    assert r.wave_surface_n[0] == pytest.approx(_brute_force_waves(p, 2.0, None), rel=1e-6)
    # Vennell et al. 2006: small once ~0.5-0.7 m under; here under a fifth at 0.5 m
    assert r.wave_submerged_n[0] < 0.2 * r.wave_surface_n[0]
    s = r.summary()
    assert s["tow_drag_coefficient_surface"] > s["tow_drag_coefficient"]
