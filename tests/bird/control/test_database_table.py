"""A controller database flies with the feather table, the dove and the reference wingbeat
it was sampled with."""

import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control.controller import bundled_database_path, database_table, load_controller
from flapsim.bird.control.database import load_database, save_database
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.tasks import path_shapes as paths
from flapsim.bird.tasks.flight_tasks import Task, build_flight
from flapsim.core.errors import InputError


@pytest.fixture(scope="module")
def revolving_db(tmp_path_factory):
    """The bundled samples relabelled as sampled with ``dove_revolving`` (the label is what
    is under test, not the samples)."""
    src = load_database(bundled_database_path())
    head = {k: v for k, v in src.header.items() if k != "fields"}
    head["config"] = {**head["config"], "table": "dove_revolving"}
    path = tmp_path_factory.mktemp("db") / "revolving.db"
    save_database(path, head, np.arange(300), {k: v[:300] for k, v in src.arrays.items()}, {})
    return path


def test_the_bundled_database_names_its_table():
    assert database_table() == FlightConfig.table == "dickinson1999_profile"


def test_a_flight_with_another_table_is_refused(revolving_db):
    fl = DoveFlight(Dove.load(), table="dove_revolving")
    try:
        with pytest.raises(InputError, match="sampled with the dickinson1999_profile feather table") as e:
            load_controller(fl)
        assert "\n" not in str(e.value) and "--table dickinson1999_profile" in str(e.value)
        assert load_controller(fl, revolving_db).regressor.n == 600  # 300 and their mirror images
    finally:
        fl.close()


def test_tasks_fly_with_the_databases_table(revolving_db):
    fl, ctl = build_flight(Task(paths.straight(20.0)), revolving_db)
    try:
        assert fl.table == "dove_revolving" and ctl.flight is fl
    finally:
        fl.close()
    fl, _ = build_flight(Task(paths.straight(20.0)))
    try:
        assert fl.table == "dickinson1999_profile"
    finally:
        fl.close()


@pytest.mark.parametrize("args, fragment", [
    (["--samples", "10", "--table", "nope"], "unknown coefficient table 'nope'"),
    (["--samples", "10", "--tail-bias-deg", "45"], "--tail-bias-deg must be within -40..40"),
    (["--samples", "10", "--twist-bias-deg", "45"], "--twist-bias-deg must be within -30..30"),
    (["--samples", "10", "--phase", "2", "--from", "x.db", "--table", "dove_revolving"],
     "--table, --tail-bias-deg, --twist-bias-deg, --induced and --cruise are for phase 1"),
    (["--samples", "10", "--phase", "2", "--from", "x.db", "--induced"],
     "--table, --tail-bias-deg, --twist-bias-deg, --induced and --cruise are for phase 1"),
    (["--samples", "10", "--induced", "--feathers", "modal"], "--induced needs rigid feathers"),
    (["--merge", "a.db", "b.db", "--table", "dove_revolving"], "--table is for training"),
])
def test_train_table_options_bad_values(capsys, tmp_path, args, fragment):
    from flapsim.cli.main import main

    code = main(["train", *args, "--out", str(tmp_path / "out.db")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and fragment in err and "\n" not in err, err
    assert not (tmp_path / "out.db").exists()


def test_train_induced_samples_the_dove_that_sees_its_downwash():
    from flapsim.cli.commands.train import phase1
    from flapsim.cli.main import build_parser

    def config(*extra):
        args = build_parser().parse_args(["train", "--samples", "10", "--out", "x.db", *extra])
        return phase1(args)[0]

    # the paper's dove, the same dove with its induced flow, and the cruise dove (which has it)
    assert (config().induced, config("--induced").induced, config("--cruise").induced) == (
        False, True, True)
    # nothing else changes with it: the capture, table and speed stay the paper's
    assert (config("--induced").capture_preset, config("--induced").cruise_speed) == (
        config().capture_preset, config().cruise_speed)


def test_twist_bias_moves_only_the_shoulder_twists():
    from flapsim.bird.body.params import DOF_NAMES
    from flapsim.bird.flight.wingbeat import p0, with_tail_bias, with_twist_bias
    from flapsim.bird.training.sampling import SamplingConfig

    base = with_tail_bias(p0(), 17.0)
    p = with_twist_bias(base, -8.0)
    moved = np.flatnonzero(p != base)
    want = sorted(2 * DOF_NAMES.index(f"{s}_shoulder_twist") + 1 for s in "lr")
    assert moved.tolist() == want
    np.testing.assert_allclose(p[moved] - base[moved], np.radians(-8.0), rtol=0, atol=1e-15)
    # the bundled database's configuration (no such key) reads back as no bias, and a
    # configuration without a bias writes none (its header stays as it was)
    cfg = SamplingConfig.from_dict(load_database(bundled_database_path()).header["config"])
    assert cfg.twist_bias_deg == 0.0 and "twist_bias_deg" not in cfg.to_dict()
    assert SamplingConfig(twist_bias_deg=-8.0).to_dict()["twist_bias_deg"] == -8.0
    with pytest.raises(InputError, match="--twist-bias-deg must be within"):
        SamplingConfig(twist_bias_deg=45.0).validate()


def test_train_options_reach_the_sampling_configuration(tmp_path):
    import argparse

    from flapsim.cli.commands import train

    p = argparse.ArgumentParser()
    train.add_arguments(p)
    p.add_argument("--seed", type=int, default=0)  # every command's (flapsim.cli.main)
    args = p.parse_args(["--samples", "10", "--out", str(tmp_path / "o.db"), "--table", "dove_revolving",
                         "--tail-bias-deg", "25", "--twist-bias-deg", "-8"])
    cfg, _ = train.phase1(args)
    assert (cfg.table, cfg.tail_bias_deg, cfg.twist_bias_deg) == ("dove_revolving", 25.0, -8.0)
    cfg, _ = train.phase1(p.parse_args(["--samples", "10", "--out", str(tmp_path / "o.db")]))
    assert (cfg.table, cfg.tail_bias_deg, cfg.twist_bias_deg) == ("dickinson1999_profile", 17.0, 0.0)


def test_the_cruise_database_flies_its_own_dove_and_reference():
    from flapsim.bird.control.controller import database_dove, database_speed
    from flapsim.bird.flight.dove_flight import CRUISE
    from flapsim.bird.flight.wingbeat import reference_wingbeat

    db = bundled_database_path("cruise")
    assert database_table(db) == "bird_wing" and database_speed(db) == CRUISE.speed == 8.5
    dove = database_dove(db)
    assert dove.induced and not database_dove().induced
    # the flight starts on the default (slow) reference; loading the database moves it onto
    # the cruise capture's, which its samples' wingbeats are offsets from (1e-9: the JSON header
    # and a refit of the same capture agree to the last bits only on the same machine)
    fl = DoveFlight(dove, table="bird_wing", use_rollout=False)
    try:
        assert np.array_equal(fl.ref.coef, reference_wingbeat().coef)
        ctl = load_controller(fl, db)
        cruise = reference_wingbeat("cruise")
        assert np.allclose(fl.ref.coef, cruise.coef, rtol=0, atol=1e-9)
        assert fl.ref.period == pytest.approx(cruise.period, rel=1e-12)
        assert ctl.P0[2 * 12 + 1] == pytest.approx(np.radians(CRUISE.tail_bias_deg))
        # its dove spirals without the lateral regulator, so a cruise database flies with it
        assert ctl.lateral is not None and ctl.lookahead is None
    finally:
        fl.close()


def test_a_pitched_databases_tasks_start_at_its_pitch(revolving_db, tmp_path):
    from flapsim.bird.control.controller import database_pitch
    from flapsim.bird.flight.dove_flight import pitch_roll
    from flapsim.bird.tasks.path_control import start_on_path

    # the paper's databases carry no centre: level starts, as ever
    assert database_pitch() == 0.0 == database_pitch(revolving_db)
    src = load_database(revolving_db)
    head = {k: v for k, v in src.header.items() if k != "fields"}
    head["config"] = {**head["config"], "pitch_centre_deg": 18.0}
    path = tmp_path / "pitched.db"
    save_database(path, head, np.arange(300), {k: v[:300] for k, v in src.arrays.items()}, {})
    assert database_pitch(path) == 18.0
    fl = DoveFlight(Dove.load(), table="dove_revolving")
    try:
        start_on_path(fl, load_controller(fl, path).P0, paths.straight(20.0), 8.5,
                      pitch_deg=database_pitch(path))
        # nose up 18 deg along the path's tangent (+x), the velocity level along it
        pitch, roll = pitch_roll(fl.data.xmat[1].reshape(3, 3))
        assert np.degrees(pitch) == pytest.approx(18.0, abs=1e-9) and abs(roll) < 1e-12
        np.testing.assert_allclose(fl.data.qvel[0:3], [8.5, 0.0, 0.0], atol=1e-12)
    finally:
        fl.close()
