"""What the dove's wings can do within the capture's own wingbeats: a global search over
changes of the reference wingbeat P0 (tail bias 17 deg), each parameter within ``--bound``
standard deviations of the capture cycles' spread about P0 (the phase-1 sampler's sigma is 3:
every candidate is a wingbeat it could draw).

    python studies/dove_wingbeat_search.py --objective cruise|climb|steady-climb|steer
        [--bound 3] [--speed 7] [--workers 2] [--maxiter 60] [--popsize 10] [--seed 0]
        [--cruise] [--json out.json]

``--cruise`` searches around the cruise dove instead (its capture's reference and spread, tail
bias 26 deg, the bird wing's section and the induced flow: ``flapsim fly --cruise``);
``--table bird_wing --induced`` flies the paper's capture under the bird wing's section.

Each candidate is flown free, repeated ``--wingbeats`` times from the standard cruise start
(level, at ``--speed``), and measured over wingbeats ``--skip``.. by
:func:`flapsim.bird.flight.power.wingbeat_balance`: the servos' mean power (generalized actuator
force times the step's mean velocity), its climb and acceleration rates, its pitch and its
heading per wingbeat. A search finds what is possible, not a bound on it.

Objectives:

* ``cruise``: the least servo power of a wingbeat that neither sinks nor slows (each m/s of
  sink costs 20 W and each m/s^2 of deceleration 10 W in the score, far beyond what a
  trimmed wingbeat saves) and holds its pitch (0.2 W a degree of drift): the cheapest
  trimmed cruise the capture's variation allows. P0 itself costs 14.4 W and loses 0.73 W.
* ``climb``: the largest rate of mechanical energy gain, m (v dv/dt + g dz/dt), W: the
  surplus a climb or a tight turn draws on, less 0.2 W a degree of pitch drift (it must
  repeat). Its pitch must stay within +-30 deg and its speed within 4-10 m/s.
* ``steady-climb``: the fastest climb (as power, m g dz/dt, W) at constant speed (10 W a
  m/s^2 of acceleration either way), with the same pitch and sanity terms as ``climb``.
* ``steer``: the largest turn to the left in one wingbeat (the heading of the centre of
  mass's velocity, deg; the mirror image turns right as far), over all 29 parameters (no
  longer symmetric), the bird flying on at ``--min-speed`` (3 m/s) or more, pitched
  ``--max-pitch`` (90 deg) at most at each wingbeat's end, and sinking 1 m/s at most (the
  capture's turns were flown slowly and mostly descending, within 5 deg of level per
  wingbeat): the paper's "steering range per wingbeat" as the wings allow it (the capture's:
  -12.5..+7.0 deg).

Symmetric (but for ``steer``): the left wing's 12 numbers are searched and copied to the
right (a symmetric wingbeat neither rolls nor yaws the dove); with the tail's 4 and the
timewarp, 17 numbers. Scipy's differential evolution,
``--workers`` processes. About 0.07 s a candidate on one core; ``--maxiter 60 --popsize 10``
is ~10,000 candidates.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import differential_evolution

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import MIRROR_PERM
from flapsim.bird.flight.capture import reference_capture
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight, FlightConfig
from flapsim.bird.flight.power import wingbeat_balance
from flapsim.bird.flight.wingbeat import N_PARAMS, p0, reference_wingbeat, with_tail_bias
from flapsim.bird.training.sampling import capture_wingbeats
from flapsim.core.environment import versions
from flapsim.core.io import write_json

#: The searched parameters: (scale, translation) of the left wing's six DOF and the tail's
#: two, and the timewarp.
FREE = np.array([i for j in (*range(6), 12, 13) for i in (2 * j, 2 * j + 1)] + [N_PARAMS - 1])


def capture_spread(preset: str = "slow") -> np.ndarray:
    """Each parameter's standard deviation over the capture cycles (fitted against the
    reference), the unit of the search's bounds."""
    return capture_wingbeats(reference_capture(preset=preset), reference_wingbeat(preset)).dP.std(0)


def dove_setup(cruise: bool, table: str | None = None, induced: bool = False,
               tail_bias_deg: float | None = None) -> tuple[DoveFlight, np.ndarray, np.ndarray]:
    """The flight searched (the paper's dove, under ``table`` with or without the induced
    flow, or the cruise dove), its P0 with the tail bias and the capture's spread."""
    if cruise:
        fl = DoveFlight(Dove.load(induced=True), reference_wingbeat("cruise"), table=CRUISE.table,
                        use_rollout=False)
        return fl, with_tail_bias(p0(), CRUISE.tail_bias_deg), capture_spread("cruise")
    fl = DoveFlight(Dove.load(induced=induced), table=table or FlightConfig.table,
                    use_rollout=False)
    bias = FlightConfig.tail_bias_deg if tail_bias_deg is None else tail_bias_deg
    return fl, with_tail_bias(p0(), bias), capture_spread()


def expand(x: np.ndarray, base: np.ndarray, spread: np.ndarray) -> np.ndarray:
    """The 29-number wingbeat: ``base`` moved by ``x`` spreads on the free parameters, the
    right wing a copy of the left; or, given 29 numbers (``steer``), on every parameter."""
    p = np.array(base, float)
    if len(x) == N_PARAMS:
        return p + np.asarray(x, float) * spread
    p[FREE] += np.asarray(x, float) * spread[FREE]
    for j in range(6):
        r = MIRROR_PERM[j]
        p[2 * r], p[2 * r + 1] = p[2 * j], p[2 * j + 1]
    return p


def score(r: dict | None, objective: str, skip: int, limits: dict | None = None) -> float:
    """The candidate's score (lower is better); ``limits``: ``steer``'s ``min_speed`` (m/s)
    and ``max_pitch`` (deg)."""
    limits = limits or {"min_speed": 3.0, "max_pitch": 90.0}
    if r is None:
        return 1e3
    drift = abs(r["pitch_deg"][-1] - r["pitch_deg"][skip - 1])
    if objective == "cruise":
        return (r["power_W"] + 20.0 * max(0.0, -r["climb_m_s"]) + 10.0 * max(0.0, -r["accel_m_s2"])
                + 0.2 * drift)
    sane = max(abs(a) for a in r["pitch_deg"]) <= 30.0 and 4.0 <= r["speed_m_s"] <= 10.0
    if objective == "steer":
        # the largest turn to the left in one wingbeat, the flight still flying (the capture's
        # own turns were flown descending, so some height may be lost)
        turn = max(np.diff(r["heading_deg"]))
        flying = (r["speed_m_s"] >= limits["min_speed"] and r["climb_m_s"] >= -1.0
                  and max(abs(a) for a in r["pitch_deg"]) <= limits["max_pitch"])
        return -turn if flying else 1e2
    if objective == "steady-climb":
        # the surplus spent on height alone: no speed lost or gained on the way
        return (-r["climb_m_s"] * r["mass_kg"] * 9.81 + 10.0 * abs(r["accel_m_s2"]) + 0.2 * drift
                if sane else 1e2)
    # a climb's wingbeat must repeat: its pitch may not run away either
    return -r["energy_rate_W"] + 0.2 * drift if sane else 1e2


_WORKER: dict = {}


def _evaluate(x: np.ndarray, objective: str, wingbeats: int, skip: int,
              speed: float, min_speed: float, max_pitch: float, cruise: bool = False,
              table: str | None = None, induced: bool = False,
              tail_bias_deg: float | None = None) -> float:
    """One candidate (in a worker process: its flight built once)."""
    if "fl" not in _WORKER:
        _WORKER["fl"], _WORKER["base"], _WORKER["spread"] = dove_setup(cruise, table, induced, tail_bias_deg)
    p = expand(x, _WORKER["base"], _WORKER["spread"])
    return score(wingbeat_balance(_WORKER["fl"], p, wingbeats, skip, speed), objective, skip,
                 {"min_speed": min_speed, "max_pitch": max_pitch})


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--objective", choices=("cruise", "climb", "steady-climb", "steer"), default="cruise",
                    help="what the search maximises (see the module docstring)")
    ap.add_argument("--bound", type=float, default=3.0, help="capture spreads each way (default 3)")
    ap.add_argument("--wingbeats", type=int, default=6, help="wingbeats each candidate is flown")
    ap.add_argument("--skip", type=int, default=2, help="wingbeats flown before measuring")
    ap.add_argument("--speed", type=float, default=7.0, help="the start's forward speed, m/s")
    ap.add_argument("--min-speed", type=float, default=3.0,
                    help="steer: the end speed it must keep, m/s (default 3)")
    ap.add_argument("--max-pitch", type=float, default=90.0,
                    help="steer: the largest pitch either way at a wingbeat's end, deg (default 90)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--maxiter", type=int, default=60)
    ap.add_argument("--popsize", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cruise", action="store_true",
                    help="around the cruise dove (its capture, bird-wing section, induced flow)")
    ap.add_argument("--table", default=None,
                    help="the paper's dove under this coefficient table (default: its own)")
    ap.add_argument("--induced", action="store_true", help="the paper's dove with the induced flow")
    ap.add_argument("--tail-bias-deg", type=float, default=None,
                    help="the paper's dove's tail bias (default 17, the paper's)")
    ap.add_argument("--json", default=None)
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    if not 1 <= a.skip < a.wingbeats:
        ap.error("need 1 <= --skip < --wingbeats")
    if a.cruise and (a.table or a.induced or a.tail_bias_deg is not None):
        ap.error("--cruise has its own table, induced flow and tail bias: leave out "
                 "--table/--induced/--tail-bias-deg")
    args = (a.objective, a.wingbeats, a.skip, a.speed, a.min_speed, a.max_pitch, a.cruise,
            a.table, a.induced, a.tail_bias_deg)
    t = time.perf_counter()
    gen = [0]

    def report(intermediate_result) -> None:
        gen[0] += 1
        if gen[0] % 10 == 0:
            print(f"  generation {gen[0]}: best score {intermediate_result.fun:.3f} "
                  f"({time.perf_counter() - t:.0f} s)", flush=True)

    n_free = N_PARAMS if a.objective == "steer" else len(FREE)
    res = differential_evolution(_evaluate, [(-a.bound, a.bound)] * n_free, args=args,
                                 maxiter=a.maxiter, popsize=a.popsize, seed=a.seed, tol=1e-6,
                                 workers=a.workers, updating="deferred", polish=False,
                                 init="sobol", x0=np.zeros(n_free), callback=report)
    wall = time.perf_counter() - t
    fl, base, spread = dove_setup(a.cruise, a.table, a.induced, a.tail_bias_deg)
    best_p = expand(res.x, base, spread)
    rows = {"P0": wingbeat_balance(fl, base, a.wingbeats, a.skip, a.speed),
            "best": wingbeat_balance(fl, best_p, a.wingbeats, a.skip, a.speed)}
    for name, r in rows.items():
        print(f"{name:5s} servos {r['power_W']:6.2f} W, energy rate {r['energy_rate_W']:+6.2f} W, "
              f"climb {r['climb_m_s']:+.3f} m/s, accel {r['accel_m_s2']:+.3f} m/s^2, end "
              f"{r['speed_m_s']:.2f} m/s, pitch {r['pitch_deg'][a.skip - 1]:+.1f} -> "
              f"{r['pitch_deg'][-1]:+.1f} deg, turns per wingbeat "
              f"{', '.join(f'{t:+.1f}' for t in np.diff(r['heading_deg']))} deg")
    print(f"{res.nfev} candidates in {wall:.0f} s on {a.workers} workers; largest move "
          f"{np.abs(res.x).max():.2f} spreads")
    if a.json:
        write_json(a.json, {"objective": a.objective, "bound_spreads": a.bound, "speed": a.speed,
                            "wingbeats": a.wingbeats, "skip": a.skip, "min_speed": a.min_speed,
                            "max_pitch": a.max_pitch, "cruise": a.cruise, "table": a.table,
                            "induced": a.induced, "tail_bias_deg": a.tail_bias_deg, "score": float(res.fun),
                            "x_spreads": res.x.tolist(), "wingbeat": best_p.tolist(),
                            "candidates": int(res.nfev), "wall_s": wall, "flights": rows,
                            "environment": versions()})


if __name__ == "__main__":
    main()
