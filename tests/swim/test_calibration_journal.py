"""The swimmer's calibration journal read back: a bad line is skipped with its file and line
named (its cycles run again), a journal that is no journal is one line; before, a header
that was a list, a line without results or an index out of range were tracebacks."""

import json
import logging

import pytest

from flapsim.core.errors import DataFileError
from flapsim.swim.per_cycle import _read_journal

HEADER = {"flapsim_version": "x", "config": {"stroke": "s.toml"}}
JOBS = [("basic", 0, None, 0.0), ("basic", 0, "turn", 0.5)]


def _res(job, **kw):
    mode, k, seq, w = JOBS[job]
    return {"i": job, "layers": mode, "snapshot": k, "sequence": seq, "weight": w, "speed": 1.0,
            "start": [0.0, 0.1], "end": [0.2, 0.3], "mean": [0.1, 0.2], **kw}


def _journal(tmp_path, *lines, header=None):
    path = tmp_path / "t.json.partial.jsonl"
    head = json.dumps(header if header is not None else {"header": HEADER})
    path.write_text("\n".join([head, *lines]) + "\n")
    return path


@pytest.mark.parametrize("line, problem", [
    (json.dumps({"no_results": []}), "no list of results"),
    (json.dumps({"results": [_res(0, i=7)]}), "result index 7"),
    (json.dumps({"results": [_res(0, i="0")]}), "result index '0'"),
    (json.dumps({"results": [_res(1, sequence="roll")]}), "not of cycle 1"),
    (json.dumps({"results": [_res(1, end="far")]}), "'end'"),
    (json.dumps([1, 2]), "no list of results"),
    ('{"results": [{"i": 1, "lay', "torn"),
])
def test_a_bad_line_is_skipped_with_its_file_and_line(tmp_path, caplog, line, problem):
    path = _journal(tmp_path, json.dumps({"results": [_res(0)]}), line)
    with caplog.at_level(logging.WARNING):
        done = _read_journal(path, HEADER, JOBS)
    assert done == {0: _res(0)}  # the good line is kept, the bad one's cycles run again
    [msg] = [r.getMessage() for r in caplog.records]
    assert msg.startswith(f"{path} line 3: ") and problem in msg and "\n" not in msg


@pytest.mark.parametrize("header", [[1, 2], "text", {"other": 1}])
def test_a_header_that_is_no_journal_header_is_one_line(tmp_path, header):
    path = _journal(tmp_path, header=header)
    with pytest.raises(DataFileError, match="not a calibration journal"):
        _read_journal(path, HEADER, JOBS)


@pytest.mark.parametrize("ends, kept", [
    (None, False),                      # a held job's line without its cycles' ends
    ([[0.2, 0.3]], False),              # one end where the job swam three cycles
    ([[0.2, 0.3], [0.4, "x"], [0.6, 0.7]], False),
    ([[0.2, 0.3], [0.4, 0.5], [0.6, 0.7]], True),
])
def test_a_held_jobs_line_needs_the_end_of_each_cycle_it_swam(tmp_path, caplog, ends, kept):
    # the held calibration's turn is read off every cycle's end: a line that lacks them
    # would stop the table's assembly with a KeyError, so its cycles are run again instead
    held = _res(1) if ends is None else _res(1, ends=ends)
    path = _journal(tmp_path, json.dumps({"results": [_res(0), held]}))
    with caplog.at_level(logging.WARNING):
        done = _read_journal(path, HEADER, JOBS, lambda seq: 1 if seq is None else 3)
    assert done == ({0: _res(0), 1: held} if kept else {})
    assert ("'ends'" in caplog.text) is not kept
