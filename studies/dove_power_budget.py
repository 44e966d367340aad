"""Where the dove's muscle power goes in free flight: :func:`flapsim.bird.flight.power.power_budget`
printed (the reference wingbeat repeated from the cruise start; any coefficient table).

    python studies/dove_power_budget.py [--wingbeats 6] [--skip 2]
        [--table NAME] [--tail-bias-deg D] [--twist-bias-deg D] [--speed M_S]
        [--json out.json]
"""

from __future__ import annotations

import argparse

from flapsim.bird.flight.power import power_budget
from flapsim.core.io import write_json


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wingbeats", type=int, default=6, help="wingbeats flown in all")
    ap.add_argument("--skip", type=int, default=2, help="wingbeats flown before averaging")
    ap.add_argument("--table", default=None, help="lift/drag coefficient table (default: the dove's)")
    ap.add_argument("--tail-bias-deg", type=float, default=None,
                    help="tail bias added to P0, deg (default: the flight's)")
    ap.add_argument("--twist-bias-deg", type=float, default=0.0,
                    help="both shoulder twists added to P0, deg (+ pronates)")
    ap.add_argument("--speed", type=float, default=None, help="start speed, m/s (default 7)")
    ap.add_argument("--json", help="write the budget here")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    r = power_budget(a.wingbeats, a.skip, a.table, a.tail_bias_deg, a.twist_bias_deg,
                     speed=a.speed)
    print(f"over {r['seconds']:.3f} s of free flight (mass {r['mass_kg']:.3f} kg):")
    for key in ("muscle_W", "dampers_W", "drag_feathers_W", "drag_feathers_downstroke_W",
                "drag_feathers_upstroke_W", "drag_body_W", "friction_W", "lift_work_W",
                "mechanical_energy_rate_W", "work_rate_all_forces_W", "other_W",
                "aero_up_per_weight", "mean_speed_m_s"):
        print(f"  {key:32s} {r[key]:8.3f}")
    print("  feathers' drag dissipation by angle of attack (deg): "
          + ", ".join(f"{k} {v:.2f} W" for k, v in r["drag_feathers_by_aoa_W"].items()))
    if a.json:
        write_json(a.json, r)


if __name__ == "__main__":
    main()
