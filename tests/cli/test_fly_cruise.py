"""``flapsim fly --cruise``: the cruise dove from the command line."""

import json

import numpy as np

from flapsim.bird.flight.dove_flight import CRUISE
from flapsim.cli.main import main


def test_fly_cruise_flies_the_cruise_dove(tmp_path, capsys):
    out = tmp_path / "c.json"
    assert main(["fly", "--cruise", "--wingbeats", "4", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["capture"] == "cruise" and r["induced"] is True
    assert r["config"]["table"] == "bird_wing" == CRUISE.table
    assert r["config"]["speed"] == CRUISE.speed and r["config"]["tail_bias_deg"] == CRUISE.tail_bias_deg
    # the cruise capture beats at 8.46 Hz on average (the slow one at 9.3): the wingbeat flown
    # is the cruise reference's, not the paper's
    assert abs(r["wingbeat_hz"] - 8.46) < 0.1 and np.isfinite(r["mean_lift_per_weight"])
    # an option given beside it wins
    assert main(["fly", "--cruise", "--wingbeats", "1", "--speed", "9", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["config"]["speed"] == 9.0
    # ... the default dove's own values too: given, they are not taken for "not given"
    assert main(["fly", "--cruise", "--wingbeats", "1", "--speed", "7", "--tail-bias-deg", "17",
                 "--pitch-deg", "0", "--json", str(out)]) == 0
    cfg = json.loads(out.read_text())["config"]
    assert (cfg["speed"], cfg["tail_bias_deg"], cfg["pitch_deg"]) == (7.0, 17.0, 0.0)
    # left out, the cruise dove starts at its trimmed trunk pitch
    assert r["config"]["pitch_deg"] == CRUISE.pitch_deg == 18.0


def test_fly_cruise_with_the_learned_controller_is_one_line(tmp_path, capsys):
    code = main(["fly", "--cruise", "--controller", "learned", "--json", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--cruise flies the base controller" in err and "\n" not in err
    assert not (tmp_path / "x.json").exists()
