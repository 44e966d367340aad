"""``flapsim swim`` end to end: JSON, the track file, and one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flapsim.cli import main as cli


def test_swim_command_writes_json_and_track(tmp_path, capsys):
    out_json, out_npz = tmp_path / "s.json", tmp_path / "t.npz"
    rc = cli.main(["swim", "--stroke", "crawl", "--seconds", "4", "--figure8", "6",
                   "--json", str(out_json), "--out", str(out_npz)])
    assert rc == 0
    s = json.loads(out_json.read_text())
    assert s["command"] == "swim" and s["stroke"] == "crawl"
    assert s["target"]["kind"] == "path" and s["layers"] == ["basic stroke", "per-cycle", "continuous"]
    # 4 s at 50 samples/s, from rest: a crawler is under way (measured 0.6 m/s average)
    assert 0.3 < s["track_speed_m_s"] < 2.0
    z = np.load(out_npz)
    assert z["com"].shape == (201, 3) and z["target_path"].shape[1] == 2
    assert np.all(np.isfinite(z["muscle_power"]))
    assert "path" in capsys.readouterr().out


def test_swim_power_reports_where_the_power_goes(tmp_path, capsys):
    out_json = tmp_path / "p.json"
    rc = cli.main(["swim", "--body", "rounded", "--stroke", "crawl", "--seconds", "6",
                   "--power", "--json", str(out_json)])
    assert rc == 0
    s = json.loads(out_json.read_text())
    b = s["water_budget"]
    # each segment's slip and its work against the progress add up to its water work, and
    # the groups to the whole body's
    assert b["water_w"] == pytest.approx(sum(g["water_w"] for g in b["segments"].values()))
    # once under way the arms push the body forwards: an efficiency strictly within (0, 1)
    assert 0.0 < b["arms_froude_efficiency"] < 1.0
    # a steady swim pays its muscles' work into the water: within a third (buoyancy,
    # waves, the joint limits and the swim's own speeding up take the rest)
    assert b["water_w"] == pytest.approx(s["muscle_power_mean_w"], rel=0.35)
    # the joint groups' net powers add up to the muscle power (each joint dof in one group)
    j = s["joint_budget"]
    assert sum(g["net_w"] for g in j["groups"].values()) == \
        pytest.approx(s["muscle_power_mean_w"], rel=1e-9)
    out = capsys.readouterr().out
    assert "Froude efficiency" in out and "absorbed braking" in out


@pytest.mark.parametrize("argv, message", [
    (["--target", "1,2,3,4"], "two or three finite"),
    (["--target", "1,2,3"], "depth Z must be -50..0.5 m"),
    (["--path", "/no/such/path.csv"], "does not exist"),
    (["--out", "track.txt"], ".npz"),
    (["--no-feedback", "--layers", "cycle"], "contradicts"),
    (["--stroke", "butterfly"], "unknown stroke"),
    (["--seconds", "-1"], "--seconds"),
])
def test_swim_command_bad_input_is_one_line(tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    rc = cli.main(["swim", "--seconds", "1", *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) >= 1 and message in err[-1] and "Traceback" not in "".join(err)
    assert list(tmp_path.iterdir()) == []  # nothing half-written


def test_swim_and_sweep_plots(tmp_path):
    import imageio.v2 as imageio

    track, sweep_png = tmp_path / "track.png", tmp_path / "sweep.png"
    assert cli.main(["swim", "--stroke", "crawl", "--seconds", "8", "--figure8", "6",
                     "--plot", str(track)]) == 0
    img = imageio.imread(track)
    assert img.shape[:2] == (600, 800)  # 8 x 6 inches at 100 dpi
    # the track (~6 m swum) is drawn in blue, the path (75 m) in gray: both are there
    rgb = img[..., :3].astype(int)
    blue = (rgb[..., 2] > 180) & (rgb[..., 0] < 80) & (rgb[..., 1] < 80)
    gray = (abs(rgb[..., 0] - 128) < 12) & (abs(rgb[..., 1] - 128) < 12) & (abs(rgb[..., 2] - 128) < 12)
    assert blue.sum() > 150 and gray.sum() > 1000
    assert cli.main(["sweep", "--stroke", "crawl", "--vary", "lungs", "--values", "2,4",
                     "--seconds", "2", "--workers", "1", "--plot", str(sweep_png)]) == 0
    assert imageio.imread(sweep_png).shape[:2] == (600, 1600)
    assert cli.main(["swim", "--seconds", "1", "--plot", str(tmp_path / "x.jpg")]) == 2
