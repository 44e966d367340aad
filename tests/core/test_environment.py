"""What a result was computed with: in every command's JSON, and in an eval journal's key."""

import json
import platform

import mujoco
import numpy as np
import scipy

from flapsim import __version__
from flapsim.cli.main import main as cli_main
from flapsim.core import environment
from flapsim.scenarios import EvalOptions, runner


def test_versions_are_the_imported_packages():
    # each against the package's own attribute, not importlib.metadata's answer again
    v = environment.versions()
    assert v["flapsim"] == __version__
    assert v["python"] == platform.python_version()
    assert v["numpy"] == np.__version__ and v["scipy"] == scipy.__version__
    assert v["mujoco"] == mujoco.__version__
    assert environment.tag().startswith(f"flapsim {__version__}, python ")


def test_every_command_json_names_the_packages(tmp_path):
    out = tmp_path / "l.json"
    assert cli_main(["eval", "--list", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["environment"]["numpy"] == np.__version__


def test_an_eval_journal_of_other_packages_is_not_resumed(tmp_path, monkeypatch):
    # the same runs under another numpy may fly otherwise: their journal must not be read back
    json_path = str(tmp_path / "r.json")
    runs = [("wind-steady", EvalOptions(quick=True))]
    j = runner.open_journal(json_path, runs)
    j.open({})
    done = {"scenario": "wind-steady", "family": "flight", "status": "completed", "ok": True,
            "metrics": {}}
    j.add(0, done)
    j.close()
    assert runner.open_journal(json_path, runs).load() == {0: done}
    real = environment.versions
    monkeypatch.setattr(environment, "versions", lambda: {**real(), "numpy": "0.0.1"})
    other = runner.open_journal(json_path, runs)
    assert other.load() == {} and other.stale


def test_the_processor_is_named_where_linux_says_it():
    from pathlib import Path

    import pytest

    info = Path("/proc/cpuinfo")
    if not info.exists():
        pytest.skip("no /proc/cpuinfo (not Linux): the processor comes from platform")
    names = [ln.split(":", 1)[1].strip() for ln in info.read_text().splitlines()
             if ln.startswith("model name")]
    assert environment.versions()["cpu"] == (names[0] if names else platform.processor() or None)


def test_version_names_the_packages(capsys):
    assert cli_main(["--version"]) == 0
    out = capsys.readouterr().out.strip()
    assert out.startswith(f"flapsim {__version__} (python {platform.python_version()}, ")
    assert f"numpy {np.__version__}" in out and f"mujoco {mujoco.__version__}" in out
