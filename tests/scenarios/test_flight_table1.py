"""``flapsim eval --table1``: the paper's sweep of database sizes and neighbours, its protocol,
and its interruption."""

from __future__ import annotations

import json

import pytest

from flapsim.cli.main import main


@pytest.mark.slow
def test_table1_trains_its_databases_and_counts_k_among_the_searched_samples(tmp_path, capsys):
    # tiny databases (100 and 200 samples) on the quick figure of eight: the point is the
    # sweep's bookkeeping, not the flights. k is the paper's share of the samples the
    # regression searches: with the mirror images 2n, so 0.5 % of 2 x 200 = 2; the k sweep is on
    # the largest database: 2 / 1 / 0.3 % of 400 = 8 / 4 / 1
    js = tmp_path / "t1.json"
    main(["eval", "--table1", "--sizes", "100,200", "--quick", "--cache", str(tmp_path / "dbs"),
          "--workers", "2", "--json", str(js)])
    out = json.loads(js.read_text())
    rows = out["table1"]
    # the bundled database's seed by default (its header: seed 2), in the databases made too
    from flapsim.bird.control.database import load_database

    assert out["seed"] == 2
    assert load_database(tmp_path / "dbs" / "phase1_100.db").header["seed"] == 2
    assert [(r["samples"], r["k_percent"], r["k"]) for r in rows] == [
        (100, 0.5, 1), (200, 0.5, 2), (200, 2.0, 8), (200, 1.0, 4), (200, 0.3, 1)]
    assert (tmp_path / "dbs" / "phase1_200.db").exists()
    assert "Table I on figure8" in capsys.readouterr().out


def test_table1_runs_fly_the_papers_controller_whatever_else_was_asked():
    """Every Table I run is the paper's protocol (sec. 7): k fixed, the bank of the wingbeat's
    end, P0 every wingbeat, the trim's angle of attack in turns, the speed asked everywhere,
    independent speed and height loops; what the run was asked otherwise is overridden."""
    from flapsim.bird.control.config import ControllerConfig
    from flapsim.bird.tasks.config import PathControlConfig
    from flapsim.scenarios import EvalOptions
    from flapsim.scenarios.runner import paper_protocol

    asked = EvalOptions(controller=ControllerConfig(k_dense_share=0.01, carry=0.4, refine=2,
                                                    clip_request=0.05),
                        path_control=PathControlConfig(bank_lead_s=0.3, aoa_per_g_deg=30.0,
                                                       turn_load_factor=1.25,
                                                       climb_per_speed_deficit=0.1,
                                                       max_bank_deg=50.0),
                        speed=6.0)
    for o in (asked, EvalOptions(), EvalOptions(feathers="modal")):
        p = paper_protocol(o)
        c, t = p.controller, p.path_control
        assert (c.k_dense_share, c.carry, c.refine, t.bank_lead_s, t.aoa_per_g_deg, p.speed,
                t.turn_load_factor, t.climb_per_speed_deficit) == (0.0, 0.0, 0, 0.0, 0.0, None,
                                                                    0.0, 0.0)
        assert c.reference_hz == 0.0  # S0 at the flight's own rate
        # the dove's own bank cap
        assert t.max_bank_deg == PathControlConfig.for_dove(o.feathers).max_bank_deg
    # what the protocol does not fix stays as asked
    assert paper_protocol(asked).controller.clip_request == 0.05


def test_sigterm_while_table1_trains_exits_143_and_leaves_nothing(tmp_path, sigterm_with_workers):
    """SIGTERM while --table1 trains its databases printed "interrupted" and exited 130,
    while --help promises 143. Sent as its sampling workers start: 143, "terminated", no
    worker left, and nothing in the folder: no JSON, no journal without a sample, not even
    the cache folder the command made."""
    status, err, alive = sigterm_with_workers(
        ["eval", "--table1", "--sizes", "100", "--quick", "--cache", "dbs", "--workers", "2",
         "--json", "t.json"], tmp_path, settle_s=0.3)  # before a chunk can be done
    assert status == 143, err
    assert err.strip().splitlines()[-1] == "flapsim eval: terminated (SIGTERM)", err
    assert not alive
    assert list(tmp_path.iterdir()) == []


def test_an_interrupted_table1_says_its_samples_are_kept(tmp_path):
    """Stopped once a chunk is kept, the line says where the samples are and how to resume."""
    import argparse

    from flapsim.cli.commands.eval import resume_hint

    args = argparse.Namespace(json=None, table1=True, cache=str(tmp_path / "dbs"))
    assert resume_hint(args) == ""  # nothing trained yet
    (tmp_path / "dbs").mkdir()
    (tmp_path / "dbs" / "phase1_100.db").write_bytes(b"")
    assert resume_hint(args) == (f"; the samples trained so far are kept in {tmp_path / 'dbs'}: "
                                 "run the same command again to resume")
