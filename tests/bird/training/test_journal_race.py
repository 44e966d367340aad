"""Two runs of one training journal: the second reads which chunks are done again once it
holds the journal's lock, so the chunks the first wrote meanwhile are kept and not written
twice; a chunk written twice with the same samples is one chunk, not damage."""

import struct

import numpy as np
import pytest

from flapsim.bird.control.database import (
    DatabaseWriter,
    fields_spec,
    finalize_database,
    load_database,
)
from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker, expected_samples
from flapsim.bird.training.train import run_header, train
from flapsim.core.errors import DataFileError, InputError

CFG = FakeConfig(seed=3)
N = 60
CS = 4


class _Scripted:
    """A worker class factory named like FakeWorker (so its journal is FakeWorker's run):
    ``on_build`` runs while the pool starts (where a second run of the same command spends
    its start-up), and the k-th chunk run raises KeyboardInterrupt (Ctrl-C)."""

    __module__ = FakeWorker.__module__
    __qualname__ = FakeWorker.__qualname__

    def __init__(self, interrupt_after: int | None = None, on_build=None):
        self.interrupt_after = interrupt_after
        self.on_build = on_build
        self.ran: list[int] = []

    def __call__(self, config):
        if self.on_build is not None:
            hook, self.on_build = self.on_build, None
            hook()
        w = FakeWorker(config)
        run = w.run_chunk

        def run_chunk(start, stop):
            if self.interrupt_after is not None and len(self.ran) >= self.interrupt_after:
                raise KeyboardInterrupt
            self.ran.append(start)
            return run(start, stop)

        w.run_chunk = run_chunk
        return w


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    path = tmp_path_factory.mktemp("ref") / "ref.db"
    train(CFG, path, N, FakeWorker, chunk_size=CS, progress=False)
    return path.read_bytes()


def test_a_run_started_meanwhile_keeps_the_first_runs_chunks(reference, tmp_path):
    """The reported race: run 1 is interrupted, run 2 starts and reads 3 done chunks, run 1
    is started again and writes 7 more while run 2 starts its pool, then is interrupted;
    run 2 (which read 3) finishes. Before, run 2 wrote chunks 3..9 a second time and the
    file was refused for ever as damaged ("overlapping chunks")."""
    out = tmp_path / "A.db"
    with pytest.raises(KeyboardInterrupt):
        train(CFG, out, N, _Scripted(interrupt_after=3), chunk_size=CS, progress=False)
    assert [c[0] for c in load_database(out).chunks] == [0, 4, 8]

    first_again = _Scripted(interrupt_after=7)

    def meanwhile():
        with pytest.raises(KeyboardInterrupt):
            train(CFG, out, N, first_again, chunk_size=CS, progress=False)

    second = _Scripted(on_build=meanwhile)
    s = train(CFG, out, N, second, chunk_size=CS, progress=False)
    assert first_again.ran == [CS * k for k in range(3, 10)]
    # run 2 ran none of the 10 chunks the file held once it had the lock
    assert second.ran and min(second.ran) == 10 * CS
    assert s["samples"] == N and out.read_bytes() == reference


def test_a_run_finished_meanwhile_is_taken_as_finished(reference, tmp_path):
    out = tmp_path / "A.db"
    with pytest.raises(KeyboardInterrupt):
        train(CFG, out, N, _Scripted(interrupt_after=2), chunk_size=CS, progress=False)

    def meanwhile():
        train(CFG, out, N, FakeWorker, chunk_size=CS, progress=False)

    second = _Scripted(on_build=meanwhile)
    s = train(CFG, out, N, second, chunk_size=CS, progress=False)
    assert s["already_complete"] and second.ran == [] and out.read_bytes() == reference


def _header(w):
    h = w.header()
    return {**run_header(CFG, FakeWorker), "model_hash": h["model_hash"], "provenance": h,
            "chunk_size": CS}


def test_an_identical_duplicate_chunk_is_not_damage(tmp_path):
    w = FakeWorker(CFG)
    res = [w.run_chunk(k * CS, (k + 1) * CS) for k in range(3)]
    path = tmp_path / "j.db"
    with DatabaseWriter.create(path, {**_header(w), "fields": fields_spec(res[0].arrays)}) as dbw:
        for r in res:
            assert dbw.append(r)
        assert not dbw.append(res[1])  # the writer knows the chunk is there
    data = path.read_bytes()
    # a record written twice, as two runs of the journal that each ran it did before
    last = len(data) - _record_length(data, res)
    path.write_bytes(data + data[last:])
    db = load_database(path)
    assert db.chunks == [(r.start, r.stop, len(r.index)) for r in res]
    np.testing.assert_array_equal(db.index, np.concatenate([r.index for r in res]))
    # the rejected counts are each chunk's once: a duplicate would double them
    assert sum(db.rejected.values()) == 3 * CS - db.n
    fin = finalize_database(path)
    assert fin.n == len(expected_samples(CFG, fin.n)) and fin.header["examined"] == 3 * CS

    # the same chunk with other samples is damage, named
    other = FakeWorker(FakeConfig(seed=4)).run_chunk(2 * CS, 3 * CS)
    path2 = tmp_path / "k.db"
    with DatabaseWriter.create(path2, {**_header(w), "fields": fields_spec(res[0].arrays)}) as dbw:
        for r in res:
            dbw.append(r)
        dbw.chunks.clear()  # a writer that did not read the file under the lock
        dbw.append(other)
    with pytest.raises(DataFileError, match="overlapping chunks 8..12 and 8..12"):
        load_database(path2)


def _record_length(data, res):
    """Bytes of the journal's last record (its 16-byte record header says its payload)."""
    pos = len(data)
    # walk from the header: preamble, then records
    _, _, hlen, _ = struct.unpack_from("<8sIII", data, 0)
    at = 20 + hlen
    lengths = []
    while at < pos:
        _, _, length = struct.unpack_from("<4sIQ", data, at)
        lengths.append(16 + length)
        at += 16 + length
    assert len(lengths) == len(res)
    return lengths[-1]


def test_create_never_replaces_a_journal_made_meanwhile(tmp_path, monkeypatch):
    w = FakeWorker(CFG)
    r = w.run_chunk(0, CS)
    path = tmp_path / "j.db"
    header = {**_header(w), "fields": fields_spec(r.arrays)}
    with DatabaseWriter.create(path, header) as dbw:
        dbw.append(r)
        before = path.read_bytes()
        # a second run that saw no file a moment ago: refused, the lock holder's file untouched
        real = type(path).exists
        monkeypatch.setattr(type(path), "exists", lambda self: False if self == path else real(self))
        with pytest.raises(InputError, match="already exists"):
            DatabaseWriter.create(path, header)
        monkeypatch.undo()
        assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["j.db"]
