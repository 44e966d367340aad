"""Bad input refused in one line before any work: a damaged database before the workers
start, conflicting or empty options, out-of-range flight starts, devices as files."""

import shutil

import pytest

from flapsim.bird.control.controller import bundled_database_path
from flapsim.cli.main import main


def _one_line(capsys, command):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"flapsim {command}: error: "), err
    return err[0]


def test_eval_verifies_the_whole_database_before_any_run(tmp_path, capsys):
    """One flipped byte in the samples: every run 'failed' (exit 1) after the workers had
    started; now the CRCs are read first."""
    db = tmp_path / "flipped.db"
    shutil.copy(bundled_database_path("rigid"), db)
    data = bytearray(db.read_bytes())
    data[len(data) // 2] ^= 0x01  # in the samples, far past the header
    db.write_bytes(bytes(data))
    assert main(["eval", "--db", str(db), "--scenario", "figure8-level", "--quick",
                 "--workers", "1"]) == 2
    msg = _one_line(capsys, "eval")
    assert str(db) in msg and "CRC" in msg


@pytest.mark.parametrize("args, fragment", [
    (["--pitch-deg", "nan"], "argument --pitch-deg: must be -90..90 deg, got nan"),
    (["--tail-bias-deg", "1e9"], "argument --tail-bias-deg: must be -40..40 deg, got 1e9"),
    (["--roll-deg", "inf"], "argument --roll-deg: must be -90..90 deg"),
    (["--speed", "nan"], "argument --speed: must be 0..30 m/s"),
])
def test_fly_range_checks_its_start(capsys, args, fragment):
    """These flew and were reported as "the simulation diverged"; they are input errors."""
    assert main(["fly", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and fragment in err[0], err


@pytest.mark.parametrize("args, fragment", [
    (["eval", "--table1", "--path", "p.csv"], "drop --path"),
    (["eval", "--table1", "--sizes", ""], "--sizes is given an empty value"),
    (["eval", "--sizes", "100,200"], "--sizes is for --table1"),
    (["eval", "--table1-seed", "3", "--cache", "c"], "--table1-seed, --cache are for --table1"),
    (["eval", "--list", "--scenario", "forest"], "--list only lists"),
    (["eval", "--scenario", ""], "--scenario is given an empty value"),
    (["fly", "--table", " "], "--table is given an empty value"),
    (["train", "--samples", "8", "--out", ""], "--out is given an empty value"),
    (["swim", "--json", ""], "--json is given an empty value"),
])
def test_conflicting_or_empty_options_are_refused_before_any_work(tmp_path, capsys, monkeypatch,
                                                                  args, fragment):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.csv").write_text("x,y,z\n0,0,0\n10,0,0\n")
    assert main(args) == 2
    msg = _one_line(capsys, args[0])
    assert fragment in msg
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.csv"]  # nothing trained or written


@pytest.mark.parametrize("args, fragment", [
    (["fly", "--path", "/dev/zero"], "--path /dev/zero is not a regular file"),
    (["list", "--json", "/dev/full"], "--json /dev/full is not a regular file"),
    (["eval", "--db", "/dev/zero"], "--db /dev/zero is not a regular file"),
    (["train", "--samples", "8", "--out", "/dev/full"], "--out /dev/full is not a regular file"),
])
def test_devices_are_no_files(capsys, args, fragment):
    """Reading /dev/zero as a path grew to 24 GB until the system killed flapsim."""
    assert main(args) == 2
    assert fragment in _one_line(capsys, args[0])


def test_a_database_loader_refuses_a_device():
    from flapsim.bird.control.database import load_database
    from flapsim.core.errors import DataFileError

    with pytest.raises(DataFileError, match="not a regular file"):
        load_database("/dev/zero")


@pytest.mark.parametrize("args", [["view"], ["swim", "--viewer"]])
def test_a_viewer_without_a_display_is_one_line_and_no_log(tmp_path, monkeypatch, capsys, args):
    """GLFW's failure printed MuJoCo's error, exited 1 and left MUJOCO_LOG.TXT behind."""
    from flapsim.core.validate import display_problem

    display = ":77"
    assert display_problem(display) is not None  # no X server there on this machine
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DISPLAY", display)
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(args) == 2
    assert f"cannot open display {display}" in _one_line(capsys, args[0])
    assert list(tmp_path.iterdir()) == []


def test_an_unreachable_ray_address_is_one_line_quickly(tmp_path, capsys):
    """`--backend ray --address 127.0.0.1:1` hung for minutes printing only Ray's warnings."""
    import time

    from flapsim.core.validate import address_problem

    t0 = time.monotonic()
    assert "cannot reach the Ray cluster at 127.0.0.1:1" in address_problem("127.0.0.1:1")
    assert "must be HOST:PORT" in address_problem("nowhere")
    assert address_problem("auto") is None
    # an address nothing answers (TEST-NET-1, never routed) times out
    assert "cannot reach" in address_problem("192.0.2.1:6379", timeout_s=0.5)
    assert time.monotonic() - t0 < 10
    pytest.importorskip("ray")
    for args in (["train", "--samples", "8", "--out", str(tmp_path / "a.db")],
                 ["eval", "--scenario", "wind-steady", "--quick"]):
        assert main([*args, "--backend", "ray", "--address", "127.0.0.1:1"]) == 2
        assert "cannot reach the Ray cluster at 127.0.0.1:1" in _one_line(capsys, args[0])
    assert list(tmp_path.iterdir()) == []
