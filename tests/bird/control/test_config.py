"""The controller's tuning as configuration (flapsim.bird.control.config.ControllerConfig,
flapsim.bird.tasks.config.PathControlConfig): defaults per dove, a TOML file read back into
what was written, one-line errors for a key or a value the file should not hold, and the
command line's --config and 'flapsim list config'."""

import dataclasses
import json
import tomllib

import pytest

from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.tasks.config import PathControlConfig, control_toml, load_control_config
from flapsim.bird.tasks.flight_tasks import DEFAULT_BANK_LEAD_S, DEFAULT_MAX_BANK_DEG
from flapsim.cli.main import main
from flapsim.core.errors import DataFileError, FlapsimError, InputError


def test_each_dove_has_its_defaults():
    rigid, modal = ControllerConfig.for_dove("rigid"), ControllerConfig.for_dove("modal")
    assert rigid == ControllerConfig()
    assert (rigid.carry, rigid.refine, rigid.k_dense_share) == (0.4, 2, 0.005)
    assert (modal.carry, modal.refine, modal.k_dense_share) == (0.0, 0, 0.0)
    # the rigid dove stops its corrections near the target and simulates S0 at 1600 Hz; the
    # modal dove has no corrections to stop and simulates S0 at its flight's rate
    assert (rigid.refine_stop, rigid.reference_hz) == (0.09, 1600.0)
    assert (modal.refine_stop, modal.reference_hz) == (0.0, 0.0)
    # S0 predicted by regression is P0's end only: nothing to carry
    assert ControllerConfig.for_dove("rigid", "regression").carry == 0.0
    for feathers in ("rigid", "modal"):
        p = PathControlConfig.for_dove(feathers)
        assert p.bank_lead_s == DEFAULT_BANK_LEAD_S[feathers]
        assert p.max_bank_deg == DEFAULT_MAX_BANK_DEG[feathers]
    with pytest.raises(InputError, match="feathers"):
        ControllerConfig.for_dove("paper")


def test_a_toml_file_reads_back_into_the_configuration_written(tmp_path):
    controller = ControllerConfig(carry=0.25, refine=1, refine_goal="reachable", lookahead="off",
                                  k_dense_share=0.01, clip_request=0.05, state_weight=2.0,
                                  refine_stop=0.2, reference_hz=2000.0)
    path = PathControlConfig(max_bank_deg=50.0, bank_lead_s=0.1, aoa_per_g_deg=20.0,
                             climb_per_speed_deficit=0.05, turn_load_factor=1.3,
                             turn_speed_floor=6.0)
    f = tmp_path / "c.toml"
    f.write_text(control_toml(controller, path))
    assert ControllerConfig.from_toml(f) == controller
    assert PathControlConfig.from_toml(f) == path
    # keys left out keep the base's values: here the modal dove's
    f.write_text("[controller]\nrefine = 1\n")
    modal = ControllerConfig.for_dove("modal")
    assert ControllerConfig.from_toml(f, modal) == dataclasses.replace(modal, refine=1)
    controller, path = load_control_config(f, "modal")
    assert controller == dataclasses.replace(modal, refine=1)
    assert path == PathControlConfig.for_dove("modal")
    # and overrides in code are dataclasses.replace
    assert dataclasses.replace(controller, carry=0.1).carry == 0.1


@pytest.mark.parametrize("text, fragment", [
    ("[controller]\ncary = 0.3\n", "unknown key 'cary'"),
    ("[path]\nmax_bank = 50\n", "unknown key 'max_bank'"),
    ("[wingbeat]\ncarry = 0.3\n", "unknown top-level key 'wingbeat'"),
    ("carry = 0.3\n", "unknown top-level key 'carry'"),
    ("[controller]\nrefine = 1.5\n", "refine must be an integer"),
    ("[controller]\nrefine = true\n", "refine must be an integer"),
    ("[controller]\ncarry = \"0.3\"\n", "carry must be a number"),
    ("[controller]\nlookahead = 1\n", "lookahead must be a string"),
    ("[controller]\nrefine_goal = \"half\"\n", "refine_goal must be one of reachable, full"),
    ("[controller]\nreference_hz = 900\n", "reference_hz must be 0 (the flight's own rate) or"),
    ("[controller]\nrefine_stop = -0.1\n", "refine_stop must be a refine error >= 0"),
    ("[path]\nmax_bank_deg = 90\n", "max_bank_deg must be 10..80 deg"),
    ("[controller\n", "not valid TOML"),
])
def test_a_key_or_value_the_file_should_not_hold_is_a_one_line_error(tmp_path, text, fragment):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(DataFileError) as e:
        load_control_config(f)
    msg = str(e.value)
    assert fragment in msg and str(f) in msg and "\n" not in msg, msg


def test_the_unknown_key_error_names_the_known_keys_and_the_fix(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text("[controller]\ncary = 0.3\n")
    with pytest.raises(FlapsimError) as e:
        ControllerConfig.from_toml(f)
    assert "carry" in str(e.value) and "flapsim list config" in str(e.value)
    with pytest.raises(DataFileError, match="no such file"):
        ControllerConfig.from_toml(tmp_path / "missing.toml")


def test_list_config_prints_the_defaults_and_writes_them_as_json(tmp_path, capsys):
    js = tmp_path / "config.json"
    assert main(["list", "config", "--json", str(js)]) == 0
    printed = tomllib.loads(capsys.readouterr().out.split("results written to")[0])
    assert printed == {"controller": dataclasses.asdict(ControllerConfig()),
                       "path": dataclasses.asdict(PathControlConfig())}
    # what it prints is a file --config reads back into the defaults
    f = tmp_path / "copy.toml"
    f.write_text(control_toml())
    assert load_control_config(f) == (ControllerConfig(), PathControlConfig())
    assert json.loads(js.read_text())["config"] == printed


def test_config_changes_the_flight_and_is_recorded(tmp_path):
    # the same cruise with the defaults and as the paper flies it: S0 simulated at the flight's
    # rate, the regression's answer flown as it is (in calm cruise the default's first answer is
    # near enough and flown as it is too, so the corrections alone would not tell them apart)
    f = tmp_path / "paper.toml"
    f.write_text("[controller]\nrefine = 0\ncarry = 0.0\nreference_hz = 0.0\n")
    out = {}
    for name, extra in (("default", []), ("config", ["--config", str(f)])):
        js = tmp_path / f"{name}.json"
        assert main(["fly", "--controller", "learned", "--wingbeats", "3", "--roll-deg", "3",
                     "--json", str(js), *extra]) == 0
        out[name] = json.loads(js.read_text())
    assert out["default"]["controller_config"] == dataclasses.asdict(ControllerConfig())
    assert out["config"]["controller_config"]["refine"] == 0 and out["config"]["refine"] == 0
    assert out["config"]["max_abs_roll_deg"] != out["default"]["max_abs_roll_deg"]
