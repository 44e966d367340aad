"""Every ``flapsim bench`` target runs to the end at its smallest settings (``--quick``) and
writes the ratios it exists to report. The ratios are recomputed here from the parts the JSON
also carries: they are quotients of the same numbers, so they agree to float rounding
(``rel=1e-9``); where a ratio's parts are not in the JSON, an inequality that follows from how
the parts were timed is checked instead. Timings themselves are not asserted (a smoke run on a
loaded machine measures nothing)."""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from flapsim.cli.commands.bench import BENCHES

ROOT = Path(__file__).resolve().parents[2]
REL = 1e-9  # quotients of the JSON's own numbers: float rounding only


def _bench(target: str, tmp_path: Path, *extra: str) -> dict:
    out = tmp_path / f"{target}.json"
    env = dict(os.environ, PYTHONPATH=str(ROOT), MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    proc = subprocess.run([sys.executable, "-m", "flapsim.cli.main", "bench", target, "--quick",
                           "--json", str(out), *extra], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(out.read_text())


def _positive(x: float) -> bool:
    return math.isfinite(x) and x > 0


def _check_forces(r: dict) -> None:
    (row,) = r["rows"]  # --quick: 50 polygons only
    assert row["polygons"] == 50
    assert row["callback_over_bare_step"] == pytest.approx(row["callback_us"] / row["bare_step_us"],
                                                           rel=REL)


def _check_modal(r: dict) -> None:
    assert r["ratio_analysis_vs_bare"] == pytest.approx(r["analysis_s"] / r["bare_forward_fullM_s"],
                                                        rel=REL)


def _check_creatures(r: dict) -> None:
    assert r["creatures"]
    for c in r["creatures"].values():
        # wall >= controller + step time, so physics-only / whole >= 1 + controller / step
        assert _positive(c["realtime_factor"]) and _positive(c["controller_vs_mj_step"])
        assert c["realtime_factor_physics_only"] / c["realtime_factor"] >= \
            1.0 + c["controller_vs_mj_step"] - REL


def _check_swimmer(r: dict) -> None:
    bare = r["bare"]["us_per_step"]
    for case, ratio in (("swimmer", "cost_vs_bare_step"),
                        ("treading_feedback", "treading_feedback_cost_vs_bare_step"),
                        ("crawl_figure8", "crawl_figure8_cost_vs_bare_step")):
        c = r[case]
        assert r[ratio] == pytest.approx(c["us_per_step"] / bare, rel=REL)
        assert c["realtime_factor"] == pytest.approx(c["sim_s"] / c["wall_s"], rel=REL)
        assert c["steps"] * r["timestep_s"] == pytest.approx(c["sim_s"], rel=REL)


def _check_dove(r: dict) -> None:
    m = r["measurements"]
    assert r["cost_over_bare_step"] == pytest.approx(
        m["rollout"]["us_per_step"] / m["bare"]["us_per_step"], rel=REL)
    assert r["real_time_factor"] == pytest.approx(
        m["rollout"]["simulated_s"] / m["rollout"]["wall_s"], rel=REL)


def _check_train(r: dict) -> None:
    assert r["workers"] == 1 and r["samples"] == 2  # the --quick settings
    assert r["parallel_efficiency"] == pytest.approx(
        r["samples_per_s"] / r["in_process_samples_per_s"], rel=REL)  # one worker
    assert _positive(r["cost_over_bare_steps"])


def _check_controller(r: dict) -> None:
    m = r["measurements"]
    assert r["cost_over_base"] == pytest.approx(
        m["base"]["real_time_factor"] / m["learned"]["real_time_factor"], rel=REL)
    # the look-ahead against the flight with the same corrections without it (S0 on the flight
    # at its own rate, every correction simulated; at least one: a modal dove's default has
    # none, the look-ahead needs one): the same flight, to the bit
    twin = "learned_every_correction"
    assert r["lookahead_speedup"] == pytest.approx(
        m["learned_lookahead"]["real_time_factor"] / m[twin]["real_time_factor"], rel=REL)
    # the wingbeats simulated per wingbeat flown: every correction is refine + 1 candidates and
    # a whole reference; the default simulates its reference (on a coarser copy: that share of
    # the flight's steps) and one to refine + 1 candidates
    per = r["wingbeats_simulated_per_flown"]
    share = r["reference_hz"] * r["timestep"]
    assert 0.5 <= share <= 1.0 + 1e-9
    assert per[twin] == pytest.approx(r["lookahead_refine"] + 2, abs=1e-12)
    assert 1.0 + share - 1e-9 <= per["learned"] <= r["refine"] + 1 + share + 1e-9
    for k, v in r["over_bare_rollout"].items():
        assert v == pytest.approx(m[k]["real_time_factor"] / m["bare_rollout"]["real_time_factor"],
                                  rel=REL)


def _check_eval(r: dict) -> None:
    # --quick: the two cheapest scenarios, each flown to a verdict (their short variants may
    # lose the path: a verdict, not a failure of the run, which would say "failed")
    assert r["runs"] == 2 and len(r["statuses"]) == 2
    assert set(r["statuses"].values()) <= {"completed", "lost"}, r["statuses"]
    assert r["speedup"] == pytest.approx(r["runs_wall_s"] / r["wall_s"], rel=REL)
    assert _positive(r["simulated_s"])


CHECKS = {name[len("_check_"):]: f for name, f in globals().items() if name.startswith("_check_")}


def test_every_bench_target_is_smoke_tested():
    assert sorted(CHECKS) == sorted(BENCHES)


@pytest.mark.parametrize("target", sorted(BENCHES))
def test_bench_target_runs_and_reports_its_ratios(target, tmp_path):
    CHECKS[target](_bench(target, tmp_path))


@pytest.mark.parametrize("target", ["dove", "controller"])
def test_the_modal_doves_bench_runs_and_reports_its_ratios(target, tmp_path):
    r = _bench(target, tmp_path, "--feathers", "modal")
    assert r["feathers"] == "modal"
    CHECKS[target](r)


def test_the_cruise_doves_controller_bench_flies_its_own_dove(tmp_path):
    """A cruise database's dove has its induced flow (another model than the default's, which
    its database would refuse), flies at the database's 8.5 m/s and with its lateral regulator;
    the variants that cannot fly the regulator (the look-ahead's pair) fly without it."""
    from flapsim.bird.control.controller import bundled_database_path

    r = _bench("controller", tmp_path, "--db", str(bundled_database_path("cruise")))
    assert r["lateral_regulator"] and r["speed"] == 8.5
    CHECKS["controller"](r)
