"""Two databases used together: ``merge_databases`` / ``flapsim train --merge`` (every sample
once, both provenances, refusals as one-line errors, atomic write), and the phase-1
pre-state ranges ``--pre-velocity`` / ``--pre-angvel`` reaching the sampler and its
provenance."""

import json

import numpy as np
import pytest

from flapsim.bird.control.controller import database_speed, database_table
from flapsim.bird.control.database import load_database, merge_databases, save_database
from flapsim.cli.main import main
from flapsim.core.errors import DataFileError, InputError

P0 = [0.1, 0.2, 0.3]


def _db(path, n, seed, model="m1", p0=P0, fields=("S", "dS", "dP"), dtype=float, coef=(1.0, 2.0)):
    rng = np.random.default_rng(seed)
    arrays = {name: rng.standard_normal((n, 8 if name != "dP" else 3)).astype(dtype) for name in fields}
    header = {"kind": "dove-phase1", "model_hash": model, "seed": seed, "config": {"seed": seed},
              "provenance": {"P0": list(p0), "reference_coef": list(coef), "reference_period": 0.1,
                             "timestep": 1 / 2400, "model_hash": model}}
    # sample indices with gaps, as a trained database has (rejected samples)
    save_database(path, header, np.arange(n) * 3 + seed, arrays, {"left_range": seed + 1})
    return arrays


def test_merge_keeps_every_sample_and_both_provenances(tmp_path):
    a = _db(tmp_path / "a.db", 7, 1)
    b = _db(tmp_path / "b.db", 5, 2, dtype=np.float32)
    db = merge_databases([tmp_path / "a.db", tmp_path / "b.db"], tmp_path / "m.db")
    assert db.finalized and db.n == 12
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.db", "b.db", "m.db"]  # no temporaries
    again = load_database(tmp_path / "m.db", model_hash="m1", require_finalized=True)
    for name in ("S", "dS", "dP"):
        np.testing.assert_array_equal(again.arrays[name][:7], a[name])
        np.testing.assert_array_equal(again.arrays[name][7:], b[name].astype(float))
    np.testing.assert_array_equal(again.arrays["part"], [0] * 7 + [1] * 5)
    np.testing.assert_array_equal(again.arrays["source_index"], [1, 4, 7, 10, 13, 16, 19, 2, 5, 8, 11, 14])
    prov = again.header["provenance"]
    assert prov["P0"] == P0 and again.header["model_hash"] == "m1" and again.header["kind"] == "merged"
    assert [p["samples"] for p in prov["parts"]] == [7, 5]
    assert [p["header"]["seed"] for p in prov["parts"]] == [1, 2]
    assert all(len(p["sha256"]) == 64 for p in prov["parts"])
    assert again.rejected == {"left_range": 2 + 3}
    # a merged database merges again (its own part/source_index fields are not carried)
    _db(tmp_path / "c.db", 4, 3)
    third = merge_databases([tmp_path / "m.db", tmp_path / "c.db"], tmp_path / "m2.db")
    assert third.n == 16 and sorted(third.arrays) == ["S", "dP", "dS", "part", "source_index"]


def test_merge_refuses_sources_that_hold_the_same_samples_and_an_existing_out(tmp_path):
    """Overlapping sources counted each sample twice (and LWLR's density radii fell to 0:
    ZeroDivisionError in every flight); an existing --out was replaced without a word."""
    _db(tmp_path / "a.db", 7, 1)
    _db(tmp_path / "b.db", 5, 2)
    (tmp_path / "copy.db").write_bytes((tmp_path / "a.db").read_bytes())
    _db(tmp_path / "longer.db", 9, 1)  # the same run (seed, parameters), more samples
    merge_databases([tmp_path / "a.db", tmp_path / "b.db"], tmp_path / "m.db")
    for sources in (["a.db", "copy.db"], ["a.db", "longer.db"], ["m.db", "a.db"],
                    ["b.db", "m.db"]):
        with pytest.raises(InputError, match="same run") as e:
            merge_databases([tmp_path / s for s in sources], tmp_path / "x.db")
        assert "\n" not in str(e.value)
    finished = (tmp_path / "m.db").read_bytes()
    _db(tmp_path / "c.db", 4, 3)
    with pytest.raises(InputError, match="exists") as e:
        merge_databases([tmp_path / "a.db", tmp_path / "c.db"], tmp_path / "m.db")
    assert (tmp_path / "m.db").read_bytes() == finished
    assert main(["train", "--merge", str(tmp_path / "a.db"), str(tmp_path / "c.db"),
                 "--out", str(tmp_path / "m.db")]) == 2
    assert (tmp_path / "m.db").read_bytes() == finished
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.db", "b.db", "c.db", "copy.db", "longer.db", "m.db"]


@pytest.mark.parametrize("kw, fragment", [
    ({"model": "m2"}, "different doves"),
    ({"p0": [0.1, 0.2, 0.4]}, "differs in 'P0'"),
    ({"fields": ("dS", "dP")}, "fields"),
])
def test_merge_refuses_unlike_databases(tmp_path, kw, fragment):
    _db(tmp_path / "a.db", 4, 1)
    _db(tmp_path / "b.db", 4, 2, **kw)
    with pytest.raises(InputError) as e:
        merge_databases([tmp_path / "a.db", tmp_path / "b.db"], tmp_path / "m.db")
    assert fragment in str(e.value) and "\n" not in str(e.value)
    assert not (tmp_path / "m.db").exists()


def test_merge_takes_the_same_reference_fitted_on_another_machine(tmp_path):
    # the bundled database's reference coefficients and those of one trained here differ by
    # 5.2e-16 (the run-time least-squares fit's last bits): the same wingbeat, merged; a
    # reference 1e-6 apart (a thousand times the 1e-9 tolerance) is another one, refused
    _db(tmp_path / "a.db", 4, 1)
    _db(tmp_path / "b.db", 4, 2, coef=(1.0 + 2.2e-16, 2.0 - 4.4e-16))
    assert merge_databases([tmp_path / "a.db", tmp_path / "b.db"], tmp_path / "m.db").n == 8
    _db(tmp_path / "c.db", 4, 3, coef=(1.0, 2.0 + 2e-6))
    with pytest.raises(InputError) as e:
        merge_databases([tmp_path / "a.db", tmp_path / "c.db"], tmp_path / "m2.db")
    assert "differs in 'reference_coef'" in str(e.value)
    assert not (tmp_path / "m2.db").exists()


def test_merge_refuses_damaged_and_unfinished_files(tmp_path):
    _db(tmp_path / "a.db", 4, 1)
    (tmp_path / "bad.db").write_bytes(b"not a database")
    with pytest.raises(DataFileError) as e:
        merge_databases([tmp_path / "a.db", tmp_path / "bad.db"], tmp_path / "m.db")
    assert "\n" not in str(e.value)
    assert not (tmp_path / "m.db").exists()


def _cli(capsys, *args):
    code = main(["train", *args])
    return code, capsys.readouterr()


def test_cli_merge_writes_one_database_and_json(capsys, tmp_path):
    _db(tmp_path / "a.db", 3, 1)
    _db(tmp_path / "b.db", 2, 2)
    code, out = _cli(capsys, "--merge", str(tmp_path / "a.db"), str(tmp_path / "b.db"), "--out",
                     str(tmp_path / "m.db"), "--json", str(tmp_path / "m.json"))
    assert code == 0, out.err
    assert "5 samples from 2 databases" in out.out
    s = json.loads((tmp_path / "m.json").read_text())
    assert s["samples"] == 5 and [p["samples"] for p in s["parts"]] == [3, 2]
    assert load_database(tmp_path / "m.db").n == 5


@pytest.mark.parametrize("args, fragment", [
    (["--merge", "{tmp}/a.db"], "at least two"),
    (["--merge", "{tmp}/a.db", "{tmp}/a.db"], "the same database twice"),
    (["--merge", "{tmp}/a.db", "{tmp}/missing.db"], "does not exist"),
    (["--merge", "{tmp}/a.db", "{tmp}/m.db"], "name the same file"),
    (["--merge", "{tmp}/a.db", "{tmp}/b.db", "--samples", "10"], "--samples is for training"),
    (["--merge", "{tmp}/a.db", "{tmp}/b.db", "--pre-velocity", "2"], "--pre-velocity is for training"),
    (["--samples", "10", "--pre-velocity", "-1"], "--pre-velocity must be 0..10"),
    (["--samples", "10", "--pre-velocity", "nan"], "--pre-velocity must be 0..10"),
    (["--samples", "10", "--pre-angvel", "1000"], "--pre-angvel must be 0..720"),
    (["--pre-angvel", "10"], "--samples N is required"),
    (["--samples", "10", "--pre-speed", "0.5"], "--pre-speed (the cruise speed) must be 1..20"),
    (["--samples", "10", "--centre-timewarp", "0"], "--centre-timewarp must be within 0.5..2"),
    (["--samples", "10", "--centre-flap-scale", "nan"], "--centre-flap-scale must be within 0.5..2"),
    (["--samples", "10", "--phase", "2", "--from", "{tmp}/a.db", "--centre-timewarp", "0.9"],
     "are for phase 1"),
    (["--merge", "{tmp}/a.db", "{tmp}/b.db", "--pre-speed", "5"], "--pre-speed is for training"),
])
def test_cli_merge_and_pre_state_bad_arguments(capsys, tmp_path, args, fragment):
    _db(tmp_path / "a.db", 3, 1)
    _db(tmp_path / "b.db", 2, 2)
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    code, out = _cli(capsys, *args, "--out", str(tmp_path / "m.db"))
    err = out.err.strip()
    assert code == 2 and fragment in err and "\n" not in err, err
    assert not (tmp_path / "m.db").exists()


def test_pre_state_ranges_reach_the_sampler_and_its_provenance():
    """--pre-velocity / --pre-angvel set the sampler's ranges (stored with the database's
    configuration), and the pre-states drawn fill them: body velocity within +-V of cruise
    per axis, angular velocity within +-W deg/s per axis."""
    import argparse

    from flapsim.bird.training.sampling import SampleWorker
    from flapsim.cli.commands.train import phase1

    args = argparse.Namespace(seed=3, sigma=None, pre_pitch_deg=30.0, pre_roll_deg=30.0, pre_velocity=4.0,
                              pre_angvel=60.0, feathers="rigid")
    cfg, worker_cls = phase1(args)
    assert worker_cls is SampleWorker
    d = cfg.to_dict()
    assert (d["linvel"], d["angvel_deg_s"], d["pitch_deg"], d["roll_deg"]) == (4.0, 60.0, 30.0, 30.0)
    w = SampleWorker(cfg)
    try:
        import mujoco

        v, om = [], []
        for i in range(60):
            w.pre_state(np.random.default_rng([3, i]))
            R = np.zeros(9)
            mujoco.mju_quat2Mat(R, w.flight.data.qpos[3:7])
            v.append(R.reshape(3, 3).T @ w.flight.data.qvel[0:3] - [cfg.cruise_speed, 0.0, 0.0])
            om.append(np.degrees(w.flight.data.qvel[3:6]))
    finally:
        w.close()
    v, om = np.abs(v), np.abs(om)
    # uniform within +-4 m/s and +-60 deg/s: 60 draws reach beyond 3 and 45 on every axis
    # (probability of missing it on one axis 0.75^60 ~ 3e-8)
    assert v.max() <= 4.0 + 1e-9 and np.all(v.max(axis=0) > 3.0)
    assert om.max() <= 60.0 + 1e-9 and np.all(om.max(axis=0) > 45.0)


def _draw_offsets(plain, moved, n: int = 30) -> list:
    """The moved sampler's wingbeat less the plain one's ellipse draw, for the same (seed 3,
    i) draws; those the moved one refuses (out of a joint range) left out."""
    offsets = []
    for i in range(n):
        a = plain.ellipses.draw(np.random.default_rng([3, i]), plain.config.sigma)[0]
        b = moved.draw_wingbeat(np.random.default_rng([3, i]))
        if b is not None:
            offsets.append(b - a)
    return offsets


def test_sampling_centre_and_pre_speed_reach_the_sampler():
    """--centre-flap-scale / --centre-timewarp move every drawn wingbeat by the same offset
    (the same random draw otherwise: sample i depends on (seed, i) alone), and --pre-speed
    moves the pre-states' body velocity; defaults leave the stored configuration as it was
    (the bundled database's has none of these keys)."""
    import argparse

    from flapsim.bird.body.params import DOF_NAMES
    from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
    from flapsim.cli.commands.train import phase1

    d0 = SamplingConfig(seed=3, pitch_deg=10.0, roll_deg=10.0).to_dict()
    assert not {"centre_flap_scale", "centre_timewarp"} & set(d0) and d0["cruise_speed"] == 7.0
    args = argparse.Namespace(seed=3, sigma=None, pre_pitch_deg=10.0, pre_roll_deg=10.0,
                              pre_speed=5.5, centre_flap_scale=1.1, centre_timewarp=0.9,
                              feathers="rigid")
    cfg, _ = phase1(args)
    d = cfg.to_dict()
    assert (d["cruise_speed"], d["centre_flap_scale"], d["centre_timewarp"]) == (5.5, 1.1, 0.9)
    plain, moved = SampleWorker(SamplingConfig(**d0)), SampleWorker(cfg)
    try:
        offsets = _draw_offsets(plain, moved)
        # P0's flap scales are 1 and its timewarp 1: the centre is +0.1 on both flap scales
        # and -0.1 on the timewarp, nothing else
        expect = np.zeros(len(plain.P0))
        for side in "lr":
            expect[2 * DOF_NAMES.index(f"{side}_shoulder_flap")] = 0.1
        expect[-1] = -0.1
        assert len(offsets) >= 10
        np.testing.assert_allclose(offsets, np.tile(expect, (len(offsets), 1)), atol=1e-12)
        import mujoco

        moved.pre_state(np.random.default_rng([3, 0]))
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, moved.flight.data.qpos[3:7])
        v = R.reshape(3, 3).T @ moved.flight.data.qvel[0:3]
        assert abs(v[0] - 5.5) <= 0.3 + 1e-9  # the paper's +-0.3 m/s around the new cruise
    finally:
        plain.close()
        moved.close()


def test_a_centre_wingbeat_reaches_the_sampler_and_its_provenance(tmp_path):
    """--centre-wingbeat FILE (a searched wingbeat, as scripts/dove_wingbeat_search.py writes
    it) moves every drawn wingbeat by (centre - P0), the same random draw otherwise, and is
    stored with the configuration and read back from it."""
    import argparse

    from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
    from flapsim.cli.commands.train import phase1

    d0 = SamplingConfig(seed=3, pitch_deg=10.0, roll_deg=10.0).to_dict()
    assert "centre_wingbeat" not in d0  # the bundled database's configuration is unchanged
    plain = SampleWorker(SamplingConfig(**d0))
    offset = np.zeros(len(plain.P0))
    offset[0], offset[1], offset[-1] = 0.05, np.radians(1.0), -0.02  # left flap scale, shift; beat
    centre = plain.P0 + offset
    (tmp_path / "c.json").write_text(json.dumps({"objective": "steady-climb",
                                                 "wingbeat": centre.tolist()}))
    args = argparse.Namespace(seed=3, sigma=None, pre_pitch_deg=10.0, pre_roll_deg=10.0,
                              centre_wingbeat=str(tmp_path / "c.json"), feathers="rigid")
    cfg, _ = phase1(args)
    d = cfg.to_dict()
    assert d["centre_wingbeat"] == centre.tolist()
    assert SamplingConfig.from_dict(json.loads(json.dumps(d))) == cfg  # through a header's JSON
    moved = SampleWorker(cfg)
    try:
        offsets = _draw_offsets(plain, moved)
        assert len(offsets) >= 10
        np.testing.assert_allclose(offsets, np.tile(offset, (len(offsets), 1)), atol=1e-12)
    finally:
        plain.close()
        moved.close()


@pytest.mark.parametrize("content, extra, fragment", [
    (None, [], "does not exist"),
    ("not json", [], "is not a JSON file"),
    ('{"wingbeat": "x"}', [], "holds no list of numbers"),
    ("[1, 2, 3]", [], "must be 29 finite wingbeat parameters"),
    (json.dumps([1.0] * 29), ["--centre-flap-scale", "1.1"], "leave out --centre-flap-scale"),
    (json.dumps([1.0] * 28 + [5.0]), [], "timewarp within 0.5..2"),
])
def test_bad_centre_wingbeats_are_one_line(capsys, tmp_path, content, extra, fragment):
    f = tmp_path / "c.json"
    if content is not None:
        f.write_text(content)
    code, out = _cli(capsys, "--samples", "4", "--centre-wingbeat", str(f), *extra,
                     "--out", str(tmp_path / "x.db"))
    err = out.err.strip()
    assert code == 2 and fragment in err and "\n" not in err, err
    assert not (tmp_path / "x.db").exists()


def test_centre_wingbeat_is_for_phase_1_training_only(capsys, tmp_path):
    _db(tmp_path / "a.db", 3, 1)
    _db(tmp_path / "b.db", 2, 2)
    (tmp_path / "c.json").write_text(json.dumps([1.0] * 29))
    for args, fragment in ((["--merge", str(tmp_path / "a.db"), str(tmp_path / "b.db")],
                            "--centre-wingbeat is for training"),
                           (["--samples", "4", "--phase", "2", "--from", str(tmp_path / "a.db")],
                            "are for phase 1")):
        code, out = _cli(capsys, *args, "--centre-wingbeat", str(tmp_path / "c.json"),
                         "--out", str(tmp_path / "m.db"))
        err = out.err.strip()
        assert code == 2 and fragment in err and "\n" not in err, err


def test_a_reference_wingbeat_is_the_databases_p0_and_its_samples_centre(tmp_path):
    """--reference-wingbeat FILE replaces P0 itself: the header's P0 (which the controller
    predicts with and measures its trim from) is the file's wingbeat, the wingbeats drawn move
    with it (the same random draw otherwise), and it survives the header's JSON."""
    import argparse

    from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
    from flapsim.cli.commands.train import phase1

    d0 = SamplingConfig(seed=3, pitch_deg=10.0, roll_deg=10.0).to_dict()
    assert "reference_wingbeat" not in d0  # the bundled database's configuration is unchanged
    plain = SampleWorker(SamplingConfig(**d0))
    offset = np.zeros(len(plain.P0))
    offset[0], offset[1], offset[-1] = 0.05, np.radians(1.0), -0.02  # left flap scale, shift; beat
    ref = plain.P0 + offset
    (tmp_path / "r.json").write_text(json.dumps({"wingbeat": ref.tolist()}))
    args = argparse.Namespace(seed=3, sigma=None, pre_pitch_deg=10.0, pre_roll_deg=10.0,
                              reference_wingbeat=str(tmp_path / "r.json"), feathers="rigid")
    cfg, _ = phase1(args)
    d = cfg.to_dict()
    assert d["reference_wingbeat"] == ref.tolist()
    assert SamplingConfig.from_dict(json.loads(json.dumps(d))) == cfg
    moved = SampleWorker(cfg)
    try:
        np.testing.assert_array_equal(moved.header()["P0"], ref)
        np.testing.assert_array_equal(moved.centre, np.zeros(len(ref)))  # drawn around itself
        # dP is P0-relative: the same draws as around the capture's P0, so every wingbeat
        # flown (P0 + dP) is the plain one's moved by the reference's offset
        offsets = _draw_offsets(plain, moved)
        assert len(offsets) >= 10
        np.testing.assert_allclose(offsets, np.zeros((len(offsets), len(ref))), atol=1e-12)
    finally:
        plain.close()
        moved.close()


@pytest.mark.parametrize("extra, fragment", [
    (["--tail-bias-deg", "20"], "leave out --tail-bias-deg"),
    (["--cruise"], "leave out --cruise"),
    (["--phase", "2", "--from", "a.db"], "are for phase 1"),
])
def test_a_reference_wingbeat_with_what_it_replaces_is_one_line(capsys, tmp_path, monkeypatch,
                                                               extra, fragment):
    monkeypatch.chdir(tmp_path)
    _db(tmp_path / "a.db", 3, 1)
    (tmp_path / "r.json").write_text(json.dumps([1.0] * 29))
    code, out = _cli(capsys, "--samples", "4", "--reference-wingbeat", "r.json", *extra,
                     "--out", str(tmp_path / "x.db"))
    err = out.err.strip()
    assert code == 2 and fragment in err and "\n" not in err, err
    assert not (tmp_path / "x.db").exists()


def _with_config(path, config):
    db = load_database(path)
    header = {**db.header, "config": config}
    path.unlink()
    save_database(path, header, db.index, db.arrays, db.rejected)


def test_a_merge_keeps_the_sampling_settings_its_sources_share(tmp_path):
    """A merge of two cruise-dove databases was flown as the default dove (no induced flow,
    the robofly table, 7 m/s, no regulator): its header held no sampling configuration, which
    is where a flight reads its dove, table, capture and start from."""
    shared = {"table": "bird_wing", "induced": True, "capture_preset": "cruise"}
    _db(tmp_path / "a.db", 4, 1)
    _db(tmp_path / "b.db", 4, 2)
    _with_config(tmp_path / "a.db", {**shared, "seed": 1, "cruise_speed": 8.5, "roll_deg": 10.0})
    _with_config(tmp_path / "b.db", {**shared, "seed": 2, "cruise_speed": 6.0, "roll_deg": 30.0})
    cfg = merge_databases([tmp_path / "a.db", tmp_path / "b.db"], tmp_path / "m.db").header["config"]
    # shared entries kept, differing ones dropped, the start (speed) the first source's
    assert cfg == {**shared, "cruise_speed": 8.5}
    assert database_table(tmp_path / "m.db") == "bird_wing"
    assert database_speed(tmp_path / "m.db") == 8.5
    # samples flown under another feather table are refused, nothing written
    _db(tmp_path / "c.db", 4, 3)
    _with_config(tmp_path / "c.db", {**shared, "table": "dickinson1999_profile", "seed": 3})
    with pytest.raises(InputError) as e:
        merge_databases([tmp_path / "a.db", tmp_path / "c.db"], tmp_path / "m2.db")
    assert "feather tables" in str(e.value) and "\n" not in str(e.value)
    assert not (tmp_path / "m2.db").exists()
