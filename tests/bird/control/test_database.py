"""The sample database file: journal appends, torn tails, finalization, and one-line
errors for foreign, damaged, newer or other-model files."""

import struct

import numpy as np
import pytest

from flapsim.bird.control.database import (
    MAGIC,
    SCHEMA_VERSION,
    DatabaseWriter,
    canonical_json,
    fields_spec,
    finalize_database,
    load_database,
    read_header,
    save_database,
)
from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker
from flapsim.core.errors import DataFileError, InputError

CS = 10


def _chunks(n_chunks, seed=0):
    w = FakeWorker(FakeConfig(seed=seed))
    return [w.run_chunk(k * CS, (k + 1) * CS) for k in range(n_chunks)]


def _journal(path, results, header_extra=None):
    header = {"model_hash": "abc123", "seed": 0, "config": {"seed": 0, "sigma": 1.0},
              "chunk_size": CS, "fields": fields_spec(results[0].arrays), **(header_extra or {})}
    with DatabaseWriter.create(path, header) as w:
        for r in results:
            w.append(r)
    return path


def _one_line_error(exc_info):
    msg = str(exc_info.value)
    assert "\n" not in msg and msg
    return msg


def test_round_trip_sorted_whatever_the_append_order(tmp_path):
    res = _chunks(4)
    _journal(tmp_path / "a.db", res)
    _journal(tmp_path / "b.db", [res[2], res[0], res[3], res[1]])
    a, b = load_database(tmp_path / "a.db"), load_database(tmp_path / "b.db")
    assert not a.finalized and a.n == sum(len(r.index) for r in res)
    assert np.all(np.diff(a.index) > 0)
    np.testing.assert_array_equal(a.index, b.index)
    for k in ("x", "y"):
        np.testing.assert_array_equal(a.arrays[k], b.arrays[k])
        np.testing.assert_array_equal(a.arrays[k], np.concatenate([r.arrays[k] for r in res]))
    assert a.arrays["y"].shape == (a.n, 2, 2) and a.arrays["x"].dtype == np.float64
    assert a.rejected == {"ends3": 4, "every7": 6}
    h = a.header
    assert h["kind"] and h["schema_version"] == SCHEMA_VERSION and h["flapsim_version"]
    assert h["model_hash"] == "abc123" and h["seed"] == 0 and h["config"]["sigma"] == 1.0
    assert h["fields"] == [{"dtype": "<f8", "name": "x", "shape": [3]},
                           {"dtype": "<f8", "name": "y", "shape": [2, 2]}]
    # finalizing either gives the same bytes
    finalize_database(tmp_path / "a.db")
    finalize_database(tmp_path / "b.db")
    assert (tmp_path / "a.db").read_bytes() == (tmp_path / "b.db").read_bytes()
    fin = load_database(tmp_path / "a.db", require_finalized=True)
    assert fin.finalized and fin.n == a.n and fin.header["examined"] == 40
    np.testing.assert_array_equal(fin.arrays["y"], a.arrays["y"])


def test_finalize_keeps_the_first_n_of_the_gap_free_prefix(tmp_path):
    res = _chunks(5)
    _journal(tmp_path / "a.db", [res[0], res[1], res[3], res[4]])  # chunk 2 missing
    with pytest.raises(InputError, match="fewer than"):
        finalize_database(tmp_path / "a.db", 16)
    db = finalize_database(tmp_path / "a.db", 10)
    assert db.n == 10 and db.header["samples"] == 10 and db.header["examined"] == 20
    np.testing.assert_array_equal(db.index, np.concatenate([res[0].index, res[1].index])[:10])
    assert sum(db.rejected.values()) == 20 - len(res[0].index) - len(res[1].index)


def test_float32_finalize_halves_the_samples_and_rounds_them(tmp_path):
    res = _chunks(4)
    _journal(tmp_path / "d.db", res)
    _journal(tmp_path / "s.db", res)
    d = finalize_database(tmp_path / "d.db")
    f = finalize_database(tmp_path / "s.db", float32=True)
    assert [x["dtype"] for x in f.header["fields"]] == ["<f4", "<f4"]
    for k in ("x", "y"):
        assert f.arrays[k].dtype == np.float32
        # exactly the double samples rounded to the nearest single
        np.testing.assert_array_equal(f.arrays[k], d.arrays[k].astype(np.float32))
    np.testing.assert_array_equal(f.index, d.index)
    # the sample payload is 4 of 8 bytes per number; index, header and framing are not
    n_numbers = sum(a.size for a in d.arrays.values())
    size = (tmp_path / "d.db").stat().st_size - (tmp_path / "s.db").stat().st_size
    assert size == 4 * n_numbers + len(canonical_json(d.header)) - len(canonical_json(f.header))


@pytest.mark.parametrize("cut", [1, 7, 16, 40])
def test_torn_tail_loads_complete_chunks_and_resumes(tmp_path, cut):
    res = _chunks(4)
    path = _journal(tmp_path / "a.db", res)
    full = path.read_bytes()
    path.write_bytes(full[:-cut])
    db = load_database(path)
    assert db.chunks == [(r.start, r.stop, len(r.index)) for r in res[:3]]
    assert db.torn_bytes == len(full) - cut - len(_journal_bytes(tmp_path, res[:3]))
    w, again = DatabaseWriter.resume(path)
    assert again.n == db.n
    w.append(res[3])
    w.close()
    assert path.read_bytes() == full


def _journal_bytes(tmp_path, res):
    p = _journal(tmp_path / "ref.db", res)
    data = p.read_bytes()
    p.unlink()
    return data


def test_zero_filled_tail_is_an_interrupted_write(tmp_path):
    path = _journal(tmp_path / "a.db", _chunks(2))
    with open(path, "ab") as fh:
        fh.write(b"\0" * 100)
    assert load_database(path).n == len(load_database(path).index) and load_database(path).torn_bytes


def test_corrupt_middle_chunk_is_an_error(tmp_path):
    path = _journal(tmp_path / "a.db", _chunks(3))
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(DataFileError) as e:
        load_database(path)
    assert "corrupt" in _one_line_error(e)


def test_finished_database_must_be_intact(tmp_path):
    path = _journal(tmp_path / "a.db", _chunks(3))
    finalize_database(path)
    path.write_bytes(path.read_bytes()[:-5])
    with pytest.raises(DataFileError) as e:
        load_database(path)
    assert "finished database" in _one_line_error(e)


@pytest.mark.parametrize("content, fragment", [
    (b"\x89PNG\r\n\x1a\n" + b"\0" * 64, "not a flapsim database (a PNG image)"),
    (b"samples: 12\nhello\n", "not a flapsim database"),
    (b"", "not a flapsim database (empty)"),
    (MAGIC[:5], "truncated header"),
    (MAGIC + struct.pack("<III", SCHEMA_VERSION, 500, 0) + b"{}", "truncated header"),
])
def test_foreign_and_truncated_files(tmp_path, content, fragment):
    path = tmp_path / "x.db"
    path.write_bytes(content)
    with pytest.raises(DataFileError) as e:
        load_database(path)
    assert fragment in _one_line_error(e)


def test_newer_schema_other_model_and_damaged_header(tmp_path):
    path = _journal(tmp_path / "a.db", _chunks(1))
    data = path.read_bytes()
    newer = tmp_path / "newer.db"
    newer.write_bytes(MAGIC + struct.pack("<I", SCHEMA_VERSION + 1) + data[12:])
    with pytest.raises(DataFileError) as e:
        load_database(newer)
    assert "newer" in _one_line_error(e) and "upgrade flapsim" in str(e.value)
    with pytest.raises(DataFileError) as e:
        read_header(newer)
    assert "newer" in _one_line_error(e)
    with pytest.raises(DataFileError) as e:
        load_database(path, model_hash="fff000")
    assert "model abc123" in _one_line_error(e) and "train" in str(e.value)
    with pytest.raises(DataFileError) as e:
        load_database(path, kind="dove-phase2")
    _one_line_error(e)
    bad = bytearray(data)
    bad[30] ^= 0x01  # inside the header JSON
    path.write_bytes(bytes(bad))
    with pytest.raises(DataFileError) as e:
        load_database(path)
    assert "corrupt header" in _one_line_error(e)
    with pytest.raises(DataFileError) as e:
        load_database(tmp_path / "missing.db")
    assert "does not exist" in _one_line_error(e)


def test_save_database_is_sorted_atomic_and_deterministic(tmp_path):
    rng = np.random.default_rng(1)
    index = np.array([9, 2, 5, 0])
    arrays = {"a": rng.standard_normal((4, 3)), "k": np.arange(4, dtype=np.int32)}
    header = {"model_hash": "m1", "seed": 4, "config": {"x": 1}, "derived_from": "phase1.db"}
    save_database(tmp_path / "d.db", header, index, arrays, {"far": 2})
    save_database(tmp_path / "e.db", header, index[::-1], {k: v[::-1] for k, v in arrays.items()},
                  {"far": 2})
    assert (tmp_path / "d.db").read_bytes() == (tmp_path / "e.db").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.db", "e.db"]  # no temporaries
    db = load_database(tmp_path / "d.db", model_hash="m1")
    assert db.finalized and db.n == 4 and db.header["derived_from"] == "phase1.db"
    np.testing.assert_array_equal(db.index, [0, 2, 5, 9])
    np.testing.assert_array_equal(db.arrays["a"], arrays["a"][[3, 1, 2, 0]])
    assert db.arrays["k"].dtype == np.int32 and db.rejected == {"far": 2}
    with pytest.raises(InputError):
        save_database(tmp_path / "f.db", header, [1, 1], {"a": np.zeros((2, 1))}, {})


def test_append_checks_the_chunk(tmp_path):
    res = _chunks(2)
    path = _journal(tmp_path / "a.db", res[:1])
    w, _ = DatabaseWriter.resume(path)
    bad = res[1]
    bad.arrays = {"x": bad.arrays["x"]}
    with pytest.raises(InputError, match="fields"):
        w.append(bad)
    with pytest.raises(InputError, match="another flapsim train"):
        DatabaseWriter.resume(path)
    w.close()
    assert load_database(path).n == len(res[0].index)
