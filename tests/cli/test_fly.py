"""``flapsim fly --controller learned``: JSON, one-line errors, nothing half-written."""

import json

from flapsim.cli.main import main


def test_learned_flight_writes_its_deviations(tmp_path, capsys):
    js = tmp_path / "f.json"
    out = tmp_path / "t.npz"
    assert main(["fly", "--controller", "learned", "--wingbeats", "4", "--roll-deg", "2",
                 "--json", str(js), "--out", str(out)]) == 0
    s = json.loads(js.read_text())
    assert s["controller"] == "learned" and s["db"] == "bundled" and s["wingbeats"] == 4
    for key in ("max_altitude_deviation", "max_speed_deviation", "max_heading_deviation_deg"):
        assert s[key] is not None and s[key] >= 0
    assert s["config"]["roll_deg"] == 2.0 and s["database_samples"] >= 1000
    assert out.exists()
    assert "largest deviations" in capsys.readouterr().out


def test_a_foreign_database_is_a_one_line_error(tmp_path, capsys):
    bad = tmp_path / "x.db"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 64)
    js = tmp_path / "f.json"
    assert main(["fly", "--controller", "learned", "--db", str(bad), "--wingbeats", "2",
                 "--json", str(js)]) == 2
    err = capsys.readouterr().err.strip()
    assert "x.db" in err and "\n" not in err
    assert not js.exists()


def test_bad_controller_options_are_refused(tmp_path, capsys):
    for args in (["--roll-deg", "nan"], ["--roll-deg", "120"], ["--k", "0"]):
        assert main(["fly", "--controller", "learned", *args]) == 2
        err = capsys.readouterr().err.strip()
        assert err and "\n" not in err
