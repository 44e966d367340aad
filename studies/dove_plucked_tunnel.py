"""Fixed-trunk "wind tunnel" with primaries plucked from the left wing: cycle-averaged
lift/weight, thrust-drag/weight and the roll and yaw moments about the trunk of the reference
wingbeat, then of left/right-asymmetric variants of it (what could hold the roll).

    python studies/dove_plucked_tunnel.py [--plucked 2,5,8] [--json out.json]

Primaries are counted from the outermost, as the paper's Fig. 15 (the ``plucked-3`` scenario:
2, 5, 8). Roll moment > 0 lifts the left wing (x forward, z up); :func:`flapsim.bird.flight.dove_flight.
wind_tunnel` with ``plucked``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from flapsim.bird.body.params import DOF_NAMES, DoveParams
from flapsim.bird.flight.dove_flight import FlightConfig, wind_tunnel
from flapsim.bird.flight.wingbeat import p0, with_tail_bias
from flapsim.core.io import write_json
from flapsim.scenarios.flight import primary_name


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--plucked", default="2,5,8", help="left primaries, from the outermost")
    ap.add_argument("--speed", type=float, default=7.0, help="headwind, m/s")
    ap.add_argument("--pitch", type=float, default=5.0, help="trunk pitch, deg")
    ap.add_argument("--json", default=None, help="write every run here")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    params = DoveParams.load()
    plucked = tuple(primary_name("l", int(i)) for i in a.plucked.split(","))
    P0 = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
    runs = [("P0, intact", P0, ()), ("P0", P0, plucked)]
    # left + delta, right - delta: the flap's scale, or an offset (deg) of one joint
    for dof, kind, deltas in (("shoulder_flap", 0, (0.1, 0.2)), ("shoulder_twist", 1, (5.0, 10.0)),
                              ("wrist_flex", 1, (-10.0, 10.0)), ("shoulder_sweep", 1, (5.0,))):
        for dl in deltas:
            p = P0.copy()
            step = dl if kind == 0 else np.radians(dl)
            p[2 * DOF_NAMES.index(f"l_{dof}") + kind] += step
            p[2 * DOF_NAMES.index(f"r_{dof}") + kind] -= step
            runs.append((f"{dof} {'scale' if kind == 0 else 'offset deg'} left {dl:+g}, right "
                         f"{-dl:+g}", p, plucked))
    print(f"left primaries {a.plucked} plucked, {a.speed:g} m/s, trunk pitch {a.pitch:g} deg")
    rows = []
    for what, p, pl in runs:
        r = wind_tunnel(params, p, a.speed, a.pitch, plucked=pl)
        rows.append({"wingbeat": what, **dataclasses.asdict(r)})
        print(f"  {what:<46} L/W {r.lift_per_weight:.3f}  T/W {r.thrust_per_weight:+.3f}  roll "
              f"{r.roll_moment * 1e3:+7.1f} mN m  yaw {r.yaw_moment * 1e3:+6.1f} mN m")
    if a.json:
        write_json(a.json, {"plucked": list(plucked), "speed": a.speed, "pitch_deg": a.pitch,
                            "runs": rows})


if __name__ == "__main__":
    main()
