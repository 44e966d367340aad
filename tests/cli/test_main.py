"""The command line: help, one-line errors, JSON output."""

import json
import subprocess
import sys

import pytest

from flapsim.cli.main import COMMANDS, main


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "flapsim.cli.main", *args], capture_output=True,
                          text=True, timeout=300)


def test_help_lists_every_command():
    r = run_cli("--help")
    assert r.returncode == 0
    for name in COMMANDS:
        assert name in r.stdout


@pytest.mark.parametrize("args, fragment", [
    (["no-such-command"], "invalid choice"),
    (["demo", "--mass", "abc"], "expected a number"),
    (["bench", "nothing"], "unknown benchmark"),
    (["demo", "--mass", "-1"], "must be 1e-06..1000 kg"),
])
def test_bad_arguments_give_one_line_errors(args, fragment):
    r = run_cli(*args)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert fragment in lines[0]
    assert "Traceback" not in r.stderr


def test_every_command_takes_json_and_seed():
    parser_help = {name: run_cli(name, "--help").stdout for name in COMMANDS}
    for name, text in parser_help.items():
        assert "--json" in text and "--seed" in text, name


def test_demo_writes_json_with_the_terminal_velocity(tmp_path, capsys):
    out = tmp_path / "demo.json"
    assert main(["demo", "--seconds", "2", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    # the plate falls flat: simulated terminal velocity within 0.1 % of sqrt(2mg/(rho A CD))
    assert data["relative_error"] < 1e-3
    assert data["command"] == "demo" and "flapsim_version" in data
    assert "terminal velocity" in capsys.readouterr().out


def test_json_into_missing_folder_is_a_clear_error(tmp_path):
    r = run_cli("demo", "--seconds", "0.1", "--json", str(tmp_path / "nope" / "x.json"))
    assert r.returncode == 2
    assert "does not exist" in r.stderr


def test_cli_routes_mujoco_warnings_to_the_log(tmp_path, monkeypatch, caplog):
    # MuJoCo would write MUJOCO_LOG.TXT into the user's folder; the CLI logs instead
    import logging

    import mujoco

    from flapsim.cli import main as cli

    monkeypatch.chdir(tmp_path)
    try:
        cli._route_mujoco_warnings()
        m = mujoco.MjModel.from_xml_string(
            '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>')
        d = mujoco.MjData(m)
        with caplog.at_level(logging.WARNING, logger="flapsim.mujoco"):
            for _ in range(2):  # the same message twice is logged once
                d.qvel[0] = 1e30
                mujoco.mj_step(m, d)
    finally:
        mujoco.set_mju_user_warning(None)
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()
    msgs = [r.getMessage() for r in caplog.records if r.name == "flapsim.mujoco"]
    assert len(msgs) == 1 and "unstable" in msgs[0]
