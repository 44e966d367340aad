"""A calibration table whose numbers are NaN was taken, and the swimmer never steered: a
data file's non-finite numbers are a one-line error naming the file and the entry."""

import json
import math
from pathlib import Path

import pytest

from flapsim.core.errors import DataFileError
from flapsim.swim.per_cycle import load_table, table_path
from flapsim.swim.strokes import load_stroke


def _nan(x):
    return [_nan(v) for v in x] if isinstance(x, list) else math.nan


@pytest.mark.parametrize("entry", ["turn_per_cycle_deg", "speeds_m_s", "level_pitch_roll_deg"])
def test_a_table_of_nan_is_refused(tmp_path, entry):
    st = load_stroke("crawl")
    d = json.loads(table_path(st).read_text())
    table = d["layers"]["cycle"]
    if entry == "turn_per_cycle_deg":
        table[entry] = {k: _nan(v) for k, v in table[entry].items()}
    else:
        table[entry] = _nan(table[entry])
    bad = tmp_path / "t.json"
    bad.write_text(json.dumps(d))  # json writes NaN, and reads it back as a float
    load_table(st, table_path(st))  # the bundled one loads
    with pytest.raises(DataFileError, match="non-finite") as e:
        load_table(st, bad)
    assert str(bad) in str(e.value) and "\n" not in str(e.value)


def test_calibrating_a_bundled_stroke_writes_to_the_users_folder(tmp_path, monkeypatch):
    """`swim --calibrate --stroke crawl` rewrote the table inside the installed package."""
    from flapsim.swim.per_cycle import STROKE_DIR

    monkeypatch.setenv("FLAPSIM_DATA", str(tmp_path / "data"))
    st = load_stroke("crawl")
    bundled = table_path(st)
    assert bundled.parent == STROKE_DIR and bundled.is_file()
    mine = table_path(st, for_writing=True)
    assert mine == tmp_path / "data" / "tables" / "crawl.cycle.json"
    assert table_path(st) == bundled  # until the user calibrates, the bundled table is read
    mine.parent.mkdir(parents=True)
    mine.write_text(bundled.read_text())
    assert table_path(st) == mine and load_table(st).speeds.size  # then the user's
    # a stroke file of the user's keeps its table beside it
    own = tmp_path / "own.toml"
    own.write_text(Path(st.path).read_text())
    assert table_path(load_stroke(str(own)), for_writing=True) == tmp_path / "own.cycle.json"
