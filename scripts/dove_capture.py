"""Regenerate the bundled SYNTHETIC dove capture (flapsim/bird/flight/data/dove_capture_synthetic.npz).

    PYTHONPATH=. python scripts/dove_capture.py [--seed 2013]
"""

from __future__ import annotations

import argparse

import numpy as np

from flapsim.bird.flight.capture import DATA_FILE
from flapsim.bird.flight.synthetic_capture import write_reference


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=2013)
    args = ap.parse_args()
    cap = write_reference(DATA_FILE, args.seed)
    f = 1.0 / cap.durations
    print(f"wrote {DATA_FILE}: {cap.n_cycles} cycles, {len(cap.angles)} frames at {cap.rate_hz} Hz")
    print(f"wingbeat {f.min():.2f}-{f.max():.2f} Hz (mean {f.mean():.2f}); steering "
          f"{cap.steering_deg.min():.1f}..{cap.steering_deg.max():.1f} deg, elevation "
          f"{cap.elevation_deg.min():.1f}..{cap.elevation_deg.max():.1f} deg, speed "
          f"{cap.speed.min():.2f}..{cap.speed.max():.2f} m/s")
    amp = np.degrees(np.ptp(cap.cycle_matrix()[:, :, 0], axis=1))
    print(f"stroke amplitude {amp.min():.0f}-{amp.max():.0f} deg")


if __name__ == "__main__":
    main()
