"""``flapsim fly --cruise``: the cruise dove from the command line."""

import json

import numpy as np

from flapsim.bird.flight.dove_flight import CRUISE
from flapsim.bird.flight.synthetic_capture import CRUISE as CRUISE_CAPTURE
from flapsim.bird.flight.wingbeat import reference_wingbeat
from flapsim.cli.main import main

KINEMATICS = CRUISE_CAPTURE[0]


def test_fly_cruise_flies_the_cruise_dove(tmp_path, capsys):
    out = tmp_path / "c.json"
    assert main(["fly", "--cruise", "--wingbeats", "4", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["capture"] == "cruise" and r["induced"] is True
    assert r["config"]["table"] == "bird_wing" == CRUISE.table
    assert r["config"]["speed"] == CRUISE.speed and r["config"]["tail_bias_deg"] == CRUISE.tail_bias_deg
    # the cruise capture's average cycle beats at ~8.5 Hz (the slow one at 9.3): the wingbeat
    # flown is the cruise reference's, not the paper's (0.1 Hz: stroke tops found to a step
    # over 4 wingbeats)
    cruise_hz = 1.0 / reference_wingbeat("cruise").period
    assert abs(r["wingbeat_hz"] - cruise_hz) < 0.1 and abs(cruise_hz - 9.3) > 0.5
    assert abs(cruise_hz - KINEMATICS.frequency_hz) < 0.1 and np.isfinite(r["mean_lift_per_weight"])
    # an option given beside it wins
    assert main(["fly", "--cruise", "--wingbeats", "1", "--speed", "9", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["config"]["speed"] == 9.0
    # ... the default dove's own values too: given, they are not taken for "not given"
    assert main(["fly", "--cruise", "--wingbeats", "1", "--speed", "7", "--tail-bias-deg", "17",
                 "--pitch-deg", "0", "--json", str(out)]) == 0
    cfg = json.loads(out.read_text())["config"]
    assert (cfg["speed"], cfg["tail_bias_deg"], cfg["pitch_deg"]) == (7.0, 17.0, 0.0)
    # left out, the cruise dove starts level, as the paper's does
    assert r["config"]["pitch_deg"] == CRUISE.pitch_deg == 0.0


def test_fly_cruise_with_the_learned_controller_is_one_line(tmp_path, capsys):
    code = main(["fly", "--cruise", "--controller", "learned", "--json", str(tmp_path / "x.json")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--cruise flies the base controller" in err and "\n" not in err
    assert not (tmp_path / "x.json").exists()
