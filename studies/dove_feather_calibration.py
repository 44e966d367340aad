"""How the modal feathers bend and twist over a wingbeat (the flight paper, sec. 7 and Fig.
3/12): the modal dove's trunk fixed in a headwind, the wings on the reference wingbeat; tip
deflection and twist of a primary, a secondary and a rectrix over one wingbeat.

    python studies/dove_feather_calibration.py --out calib [--speed 7] [--pitch-deg 5]
        [--integration engine|joints] [--no-tunnel]

Writes ``calib/feathers.png`` (deflection and twist against the wingbeat phase, downstroke
shaded) and ``calib/feathers.json`` (per feather: mean and extreme tip deflection and twist in
the downstroke and the upstroke, and the fixed-trunk lift/weight with rigid and modal
feathers). What the paper shows: the feathers bend at the downstroke and the primaries twist
open at the upstroke.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from flapsim.bird.body.feather_modes import ModalParams
from flapsim.bird.body.params import DoveParams
from flapsim.bird.flight.calibration import record, summary
from flapsim.bird.flight.dove_flight import FlightConfig, wind_tunnel
from flapsim.bird.flight.wingbeat import p0, with_tail_bias


def plot(rec: dict, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 6))
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ph, down = rec["phase"], rec["down"]
    for ax in (ax1, ax2):
        ax.fill_between(ph, 0, 1, where=down, color="0.9", transform=ax.get_xaxis_transform(),
                        label="downstroke")
    for n, r in rec["feathers"].items():
        ax1.plot(ph, 1e3 * r["deflection"], label=n)
        ax2.plot(ph, np.degrees(r["elastic_twist"] + r["hinge_twist"]), label=n)
    ax1.set_ylabel("tip deflection, mm (+ dorsal)")
    ax2.set_ylabel("twist, deg (+ trailing edge down)")
    ax2.set_xlabel("wingbeat phase (0 = top of the stroke)")
    ax1.legend(fontsize=8)
    ax1.set_title(f"modal feathers, trunk fixed at {rec['pitch_deg']:g} deg in a "
                  f"{rec['speed']:g} m/s headwind")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="dove_feather_calibration", help="output folder")
    ap.add_argument("--speed", type=float, default=7.0, help="headwind, m/s")
    ap.add_argument("--pitch-deg", type=float, default=5.0, help="trunk pitch, deg")
    ap.add_argument("--no-tunnel", action="store_true", help="skip the rigid/modal lift/weight")
    ap.add_argument("--integration", choices=("engine", "joints"), default="engine",
                    help="who integrates the modes (ModalParams.integration)")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rec = record(args.speed, args.pitch_deg, integration=args.integration)
    res = {"speed": args.speed, "pitch_deg": args.pitch_deg, "integration": args.integration,
           "feathers": summary(rec)}
    if not args.no_tunnel:
        params = DoveParams.load()
        P = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
        for name, modal in (("rigid", None), ("modal", ModalParams(integration=args.integration))):
            t = wind_tunnel(params, P, args.speed, args.pitch_deg, modal=modal)
            res[f"{name}_lift_per_weight"] = float(t.lift_per_weight)
            res[f"{name}_thrust_per_weight"] = float(t.thrust_per_weight)
    plot(rec, out / "feathers.png")
    (out / "feathers.json").write_text(json.dumps(res, indent=1))
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
