"""An output the system refuses to store (a full disk, a file-size limit) is a one-line
error naming the file, and nothing half-written is left: JSON, npz, videos (whose encoder's
failure imageio ignores) and the training journal (which says it can be resumed)."""

import errno
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from flapsim.core.errors import OutputError
from flapsim.core.io import atomic_video, check_mp4, save_npz, write_json

ROOT = Path(__file__).resolve().parents[2]


def _no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_json_and_npz_on_a_full_disk_name_the_file_and_leave_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(Path, "write_text", _no_space)
    with pytest.raises(OutputError) as e:
        write_json(tmp_path / "r.json", {"a": 1})
    msg = str(e.value)
    assert "r.json" in msg and "No space left on device" in msg and "\n" not in msg
    monkeypatch.setattr(np, "savez_compressed", _no_space)
    with pytest.raises(OutputError, match="a.npz: No space left"):
        save_npz(tmp_path / "a.npz", x=np.arange(3))
    assert list(tmp_path.iterdir()) == []


def test_the_cli_exits_1_with_one_line_on_a_full_disk(tmp_path, monkeypatch, capsys):
    from flapsim.cli.main import main

    monkeypatch.setattr(Path, "write_text", _no_space)
    assert main(["list", "--json", str(tmp_path / "l.json")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"flapsim list: error: cannot write {tmp_path / 'l.json'}: No space left on "
                   "device; nothing was written there (free space, or choose another place)"]
    assert list(tmp_path.iterdir()) == []


# ffmpeg under a 20 kB file-size limit, with SIGXFSZ ignored as a full disk never signals:
# its write fails (EFBIG), it prints the error and exits 1, leaving an MP4 without its index
_SCRIPT = textwrap.dedent("""
    import resource, sys
    import numpy as np
    resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))
    from flapsim.core.io import atomic_video
    rng = np.random.default_rng(0)
    try:
        with atomic_video(sys.argv[1], fps=10, macro_block_size=1) as frame:
            for _ in range(40):
                frame(rng.integers(0, 255, (64, 64, 3), dtype=np.uint8))
    except Exception as exc:
        print(type(exc).__name__, exc)
    else:
        print("written")
""")


def test_a_video_whose_encoder_fails_is_an_error_and_no_file(tmp_path):
    import imageio_ffmpeg

    wrapper = tmp_path / "ffmpeg"
    wrapper.write_text(f"#!/bin/sh\ntrap '' XFSZ\nexec {imageio_ffmpeg.get_ffmpeg_exe()} \"$@\"\n")
    wrapper.chmod(0o755)
    out = tmp_path / "v" / "clip.mp4"
    out.parent.mkdir()
    env = dict(os.environ, PYTHONPATH=str(ROOT), IMAGEIO_FFMPEG_EXE=str(wrapper))
    res = subprocess.run([sys.executable, "-c", _SCRIPT, str(out)], env=env, capture_output=True,
                         text=True, timeout=120)
    line = res.stdout.strip().splitlines()[-1]
    assert line.startswith(f"OutputError cannot write {out}: the video encoder"), res.stdout + res.stderr
    assert list(out.parent.iterdir()) == []  # neither the video nor its temporary


def test_an_mp4_without_its_index_is_named_unplayable(tmp_path):
    good = tmp_path / "g.mp4"
    with atomic_video(good, fps=10, macro_block_size=1) as frame:
        for i in range(5):
            frame(np.full((16, 16, 3), 40 * i, np.uint8))
    assert check_mp4(good) is None
    data = good.read_bytes()
    moov = data.find(b"moov") - 4  # ffmpeg writes the index last unless asked otherwise
    assert moov > 0
    (tmp_path / "cut.mp4").write_bytes(data[:moov])
    assert check_mp4(tmp_path / "cut.mp4") == "it has no index (moov box)"
    (tmp_path / "torn.mp4").write_bytes(data[:-10])
    assert "cut short" in check_mp4(tmp_path / "torn.mp4")


def test_a_full_disk_while_training_keeps_the_journal_resumable(tmp_path, monkeypatch):
    from flapsim.bird.control import database
    from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker
    from flapsim.bird.training.train import train

    cfg, out = FakeConfig(seed=1), tmp_path / "a.db"
    ref = tmp_path / "ref.db"
    train(cfg, ref, 40, FakeWorker, chunk_size=5, progress=False)
    real_fsync, calls = os.fsync, [0]

    def fsync(fd):  # the fourth chunk's write fails as a full disk fails it
        calls[0] += 1
        if calls[0] == 5:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(database.os, "fsync", fsync)
    with pytest.raises(OutputError) as e:
        train(cfg, out, 40, FakeWorker, chunk_size=5, progress=False)
    msg = str(e.value)
    assert str(out) in msg and "No space left on device" in msg and "resume" in msg
    assert "\n" not in msg
    # the chunks written before are whole (the failed one's bytes were cut off) ...
    assert [c[0] for c in database.load_database(out).chunks] == [0, 5, 10]
    monkeypatch.setattr(database.os, "fsync", real_fsync)
    # ... and the same call resumes to the bytes of an uninterrupted run
    train(cfg, out, 40, FakeWorker, chunk_size=5, progress=False)
    assert out.read_bytes() == ref.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.db", "ref.db"]


def test_a_full_disk_while_finishing_a_journal_keeps_it_and_says_so(tmp_path, monkeypatch, capsys):
    """Every chunk written, then the finished database (written beside the journal and
    renamed over it) meets a full disk: the journal is untouched, the line says so and how
    to resume, and the resumed run finishes to the bytes of an uninterrupted one."""
    import flapsim.cli.commands.train as cmd
    from flapsim.bird.control import database
    from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker
    from flapsim.cli.main import main

    cfg, out, ref = FakeConfig(seed=2), tmp_path / "a.db", tmp_path / "ref.db"
    monkeypatch.setattr(cmd, "phase1", lambda args: (cfg, FakeWorker))
    argv = ["train", "--samples", "40", "--chunk-size", "5", "--workers", "1", "--no-progress",
            "--out"]
    assert main([*argv, str(ref)]) == 0  # uninterrupted
    capsys.readouterr()
    real_fsync, temporaries = os.fsync, []

    def fsync(fd):  # the second temporary (the first holds the new journal's header) is the
        # finished database: only it meets the full disk
        if os.readlink(f"/proc/self/fd/{fd}").startswith(str(tmp_path / ".a.db.")):
            temporaries.append(fd)
            if len(temporaries) == 2:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(database.os, "fsync", fsync)
    argv.append(str(out))
    assert main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    held = database.load_database(out)
    assert not held.finalized and held.n >= 40  # every chunk kept, still a journal
    assert err == [f"flapsim train: error: cannot write {out}: No space left on device; the "
                   f"training journal is kept as it was ({held.n} samples in {len(held.chunks)} "
                   "chunks): free "
                   "space and run the same command again to resume (it finishes the database)"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.db", "ref.db"]  # no temporary
    monkeypatch.setattr(database.os, "fsync", real_fsync)
    assert main(argv) == 0
    assert out.read_bytes() == ref.read_bytes()
