"""Batch evaluation: swim one stroke at several values of one parameter, in parallel
processes, and tabulate the results (the paper's fluid-density sweep, and the same for
lung volume, stroke rate, skin friction or a cross current).

Processes, not threads: the passive force callback holds the GIL while it runs.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed

from flapsim.core.errors import FlapsimError, InputError
from flapsim.core.validate import RANGES
from flapsim.swim.model import SwimmerParams
from flapsim.swim.simulate import swim

#: parameter -> (SwimmerParams field or swim() argument, unit, valid range); the ranges are
#: the ones ``flapsim swim`` accepts (flapsim.core.validate.RANGES)
PARAMETERS: dict[str, tuple[str, str, tuple[float, float]]] = {
    name: (field, RANGES[name].unit, (RANGES[name].lo, RANGES[name].hi))
    for name, field in (("density", "water_density"), ("lungs", "lung_volume_l"),
                        ("rate", "rate_hz"), ("friction", "friction"), ("current", "current_y"))
}

#: summary entries tabulated (when present), with their column titles
COLUMNS = (
    ("speed_m_s", "speed m/s"), ("track_speed_m_s", "track m/s"),
    ("stroke_rate_hz", "rate Hz"), ("head_height_mean_m", "head m"),
    ("com_height_mean_m", "CoM m"), ("lateral_drift_m", "sideways m"),
    ("muscle_power_mean_w", "power W"), ("target_distance_mean_m", "to target m"),
    ("target_reached_s", "reached s"), ("path_error_mean_m", "path err m"),
    ("path_completed_fraction", "path done"),
)


def _one(job: tuple) -> dict:
    stroke, name, value, seconds, target, feedback = job

    field = PARAMETERS[name][0]
    kwargs: dict = {}
    params = {}
    if field == "rate_hz":
        kwargs["rate_hz"] = value
    elif field == "current_y":
        kwargs["current"] = (0.0, value, 0.0)
    else:
        params[field] = value
    try:
        s = swim(stroke, seconds, SwimmerParams(**params), target=target, feedback=feedback,
                 **kwargs).summary()
    except FlapsimError as exc:  # e.g. a diverging run: a row that says so
        return {"value": value, "error": str(exc)}
    s.pop("feedback_weights", None)
    return {"value": value, **s}


def sweep(stroke: str, name: str, values: Sequence[float], seconds: float = 20.0,
          target: object | None = None, feedback: bool = True, workers: int | None = None,
          on_done: Callable[[dict], None] | None = None) -> list[dict]:
    """One swim per value of parameter ``name`` (see :data:`PARAMETERS`); rows in the
    order of ``values``. ``on_done(row)`` is called as each run finishes."""
    if name not in PARAMETERS:
        raise InputError(f"cannot vary {name!r}; choose one of {', '.join(PARAMETERS)}")
    lo, hi = PARAMETERS[name][2]
    vals = [float(v) for v in values]
    if not vals:
        raise InputError("give at least one value to sweep")
    bad = [v for v in vals if not RANGES[name].contains(v)]
    if bad:
        raise InputError(f"{name} values must be within {lo:g}..{hi:g} "
                         f"{PARAMETERS[name][1]}, got {bad}")
    jobs = [(stroke, name, v, seconds, target, feedback) for v in vals]
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs)))
    rows: dict[int, dict] = {}
    if workers == 1:
        for i, job in enumerate(jobs):
            rows[i] = _one(job)
            if on_done:
                on_done(rows[i])
    else:
        pool = ProcessPoolExecutor(workers, initializer=_init_worker)
        try:
            futures = {pool.submit(_one, job): i for i, job in enumerate(jobs)}
            for fut in as_completed(futures):
                rows[futures[fut]] = fut.result()
                if on_done:
                    on_done(rows[futures[fut]])
        except BaseException:  # an error, Ctrl-C or SIGTERM: drop the queue, stop the workers
            procs = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                p.terminate()
            for p in procs:
                p.join(10)
            raise
        pool.shutdown()
    return [rows[i] for i in range(len(jobs))]


def _init_worker() -> None:
    """Workers leave Ctrl-C and SIGTERM to the parent, which stops them."""

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def table(rows: list[dict], name: str) -> str:
    """The rows as a fixed-width text table (columns present in any row)."""
    cols = [(k, t) for k, t in COLUMNS if any(k in r for r in rows)]
    unit = PARAMETERS[name][1]
    head = [f"{name} [{unit}]"] + [t for _, t in cols]
    lines = []
    for r in rows:
        if "error" in r:
            lines.append([f"{r['value']:g}", f"failed: {r['error']}"])
            continue
        cells = [f"{r['value']:g}"]
        for k, _ in cols:
            v = r.get(k)
            cells.append("-" if v is None else f"{v:.3g}" if isinstance(v, float) else str(v))
        lines.append(cells)
    widths = [max(len(head[i]), *(len(c[i]) for c in lines if i < len(c)))
              for i in range(len(head))]
    out = ["  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True))]
    for c in lines:
        if len(c) == 2 and c[1].startswith("failed"):
            out.append(c[0].rjust(widths[0]) + "  " + c[1])
        else:
            out.append("  ".join(x.rjust(w) for x, w in zip(c, widths, strict=True)))
    return "\n".join(out)
