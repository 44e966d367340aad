"""Batch evaluation over a parameter (``flapsim sweep``), in parallel processes."""

from __future__ import annotations

import json

import pytest

from flapsim.cli import main as cli
from flapsim.core.errors import InputError
from flapsim.swim.sweep import sweep, table


def test_density_sweep_in_processes_floats_higher_in_denser_water():
    # two worker processes, rows back in the order asked; the paper's Fig. 16 claim:
    # the swimmer sinks less as the water gets denser (crawl, 6 s: centre of mass
    # measured -0.25 / -0.12 / -0.05 m at 1000 / 1100 / 1300 kg/m^3)
    rows = sweep("crawl", "density", [1300.0, 1000.0, 1100.0], seconds=6.0, workers=2)
    assert [r["value"] for r in rows] == [1300.0, 1000.0, 1100.0]
    z = {r["value"]: r["com_height_mean_m"] for r in rows}
    assert z[1000.0] < z[1100.0] < z[1300.0]
    text = table(rows, "density")
    assert text.splitlines()[0].lstrip().startswith("density [kg/m^3]") and len(text.splitlines()) == 4


def test_sweep_checks_its_input():
    with pytest.raises(InputError, match="cannot vary"):
        sweep("crawl", "gravity", [1.0])
    with pytest.raises(InputError, match="within"):
        sweep("crawl", "lungs", [2.0, 9.0])
    with pytest.raises(InputError, match="at least one"):
        sweep("crawl", "rate", [])


def test_sweep_command(tmp_path, capsys):
    out, csv = tmp_path / "s.json", tmp_path / "s.csv"
    rc = cli.main(["sweep", "--stroke", "breaststroke", "--vary", "rate", "--values", "0.6,0.8",
                   "--seconds", "3", "--workers", "1", "--json", str(out), "--csv", str(csv)])
    assert rc == 0
    s = json.loads(out.read_text())
    assert [r["stroke_rate_hz"] for r in s["rows"]] == pytest.approx([0.6, 0.8])
    assert csv.read_text().splitlines()[0].startswith("value,")
    assert "rate [cycles/s]" in capsys.readouterr().out
    assert cli.main(["sweep", "--vary", "density", "--values", "1000,abc"]) == 2
    assert "comma-separated numbers" in capsys.readouterr().err
