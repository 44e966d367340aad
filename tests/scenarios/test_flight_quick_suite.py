"""Every flight scenario's quick variant flown end to end by ``flapsim eval``'s runner, and
eval stopped by SIGTERM."""

from __future__ import annotations

import pytest

from flapsim import scenarios


@pytest.mark.slow
def test_every_flight_scenario_runs_its_quick_variant_to_a_verdict(tmp_path):
    # every runner end to end (short variants, two worker processes): each gives a verdict
    # and its own numbers; 'failed' (a runner's error) or 'diverged' would be a bug here
    from flapsim.scenarios.runner import execute

    names = scenarios.names(family="flight", all_only=True)
    opts = scenarios.EvalOptions(quick=True, plots_dir=str(tmp_path))
    results = execute([(n, opts) for n in names], workers=2)
    assert [r["scenario"] for r in results] == names
    for r in results:
        assert r["status"] in ("completed", "lost"), r
        assert r["ok"] == (r["status"] == "completed")
    by = {r["scenario"]: r for r in results}
    assert by["flock"]["metrics"]["birds"] == 2 and by["flock"]["metrics"]["min_separation_m"] > 0
    for d in ("front", "back", "left", "right", "up", "down"):
        assert [row["newtons"] for row in by[f"push-{d}"]["metrics"]["table"]] == [8.0]
    assert by["forest"]["metrics"]["trees"] > 10
    # a plot per flown path (pushes: one per force; flock: one per bird)
    assert len(list(tmp_path.glob("*.png"))) >= len(names)


def test_sigterm_stops_eval_and_its_workers_leaving_no_file(tmp_path, sigterm_with_workers):
    # two long runs on two worker processes, stopped mid-flight: exit 143, no JSON, no plot
    # and no hidden temporary file in the plots folder, no worker left alive
    (tmp_path / "plots").mkdir()
    status, err, alive = sigterm_with_workers(
        ["eval", "--scenario", "figure8-level,figure8", "--workers", "2", "--plots", "plots",
         "--json", "e.json"], tmp_path, settle_s=3.0)  # the workers are flying
    assert status == 143, err
    assert err.strip().splitlines()[-1] == "flapsim eval: terminated (SIGTERM)"
    assert not alive
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["plots"]
