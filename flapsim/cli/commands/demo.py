"""``flapsim demo``: the force engine on built-in cases with hand-computable answers."""

from __future__ import annotations

import argparse

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.core.loading import load_model
from flapsim.core.stepping import step
from flapsim.core.validate import quantity
from flapsim.fluid.coefficients import flat_plate
from flapsim.fluid.flow import FlowField, Gust, Uniform
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces

HELP = "drop a plate through air and blow a gust at it: the force engine against hand-computed numbers"
SEED_HELP = "accepted for uniformity; the demo is deterministic, --seed changes nothing"

_XML = """<mujoco model="demo_plate"><option timestep="0.001"/><worldbody>
  <body name="plate" pos="0 0 20"><joint type="slide" axis="0 0 1"/>
    <joint name="x" type="slide" axis="1 0 0"/><joint name="y" type="slide" axis="0 1 0"/>
    <geom type="box" size="{h} {h} .001" mass="{m}"/></body></worldbody></mujoco>"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mass", type=quantity("mass"), default=0.01,
                   help="plate mass [kg] (default 0.01)")
    p.add_argument("--side", type=quantity("side"), default=0.2, help="plate side [m] (default 0.2)")
    p.add_argument("--seconds", type=quantity("seconds"), default=4.0,
                   help="simulated time [s] (default 4)")


def run(args: argparse.Namespace) -> dict:
    h = args.side / 2
    model = load_model(_XML.format(h=h, m=args.mass), is_xml=True)
    data = mujoco.MjData(model)
    square = np.array([[[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]]])
    table = flat_plate()
    rho = 1.225
    # a sideways 1-cosine gust halfway through the fall
    gust = Gust(direction=(0, 1, 0), amplitude=3.0, start=args.seconds / 2, duration=0.5)
    forces = SurfaceForces(model, PolygonSet.from_polygons(1, square), [table], FluidParams(rho),
                           FlowField([Uniform((0, 0, 0)), gust]))
    area = args.side**2
    v_terminal = float(np.sqrt(2 * args.mass * 9.81 / (rho * area * table.at(90.0)[1])))
    n = int(round(args.seconds / model.opt.timestep))
    vz, vy = np.empty(n), np.empty(n)
    with forces.register(data):
        for i in tqdm(range(n), desc="demo", unit="step", leave=False):
            step(model, data, what="the falling plate")  # divergence -> SimulationError
            vz[i], vy[i] = data.qvel[0], data.qvel[2]
    before_gust = -vz[int(0.45 * n)]
    result = {
        "plate": {"mass_kg": args.mass, "area_m2": area, "cd_broadside": float(table.at(90.0)[1])},
        "terminal_velocity_analytic_m_s": v_terminal,
        "terminal_velocity_simulated_m_s": float(before_gust),
        "relative_error": float(abs(before_gust - v_terminal) / v_terminal),
        "gust_peak_m_s": gust.amplitude,
        "max_sideways_speed_m_s": float(np.max(np.abs(vy))),
        "fall_distance_m": float(-data.qpos[0]),
    }
    print(f"plate {args.side:.2f} m square, {args.mass * 1000:.1f} g, falling flat through air")
    print(f"  terminal velocity: simulated {before_gust:.4f} m/s, hand-computed "
          f"sqrt(2 m g / (rho A CD)) = {v_terminal:.4f} m/s "
          f"(error {100 * result['relative_error']:.3f} %)")
    print(f"  a 3 m/s sideways gust pushed it to {result['max_sideways_speed_m_s']:.3f} m/s sideways")
    return result
