"""The continuous layer's hand rules: which face is the palm, the tables made with the
rules, and the figure of eight with and without the layer."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from flapsim.errors import DataFileError
from flapsim.scenarios.swim import _metrics
from flapsim.swim import cycle as cyc
from flapsim.swim.continuous import PALM_SIDE, calibration_settings
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import load_stroke
from flapsim.swim.targets import figure_eight


def test_the_palm_faces_the_crawls_pull():
    # the crawl's basic stroke pulls palm first: while a hand moves fast through the
    # water (the pull, > 0.5 m/s relative flow) its palm's outward normal points against
    # the water coming at it. Measured (speed-weighted mean of n . v_rel/|v_rel|): -0.65
    # left, -0.63 right; a palm normal taken on the wrong side reads +0.6
    seen = {"l": [], "r": []}
    vel = np.zeros(6)

    def hook(sw, layer):
        m, d = sw.model, sw.data
        for s in "lr":
            g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"hand_{s}")
            pos = d.geom_xpos[g]
            if pos[2] >= sw.params.water_level:
                continue
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_GEOM, g, vel, 0)
            v_rel = sw.flow.velocity(pos[None, :], float(d.time))[0] - vel[3:]
            speed = float(np.linalg.norm(v_rel))
            if speed > 0.5:
                n = d.geom_xmat[g].reshape(3, 3)[:, 1] * PALM_SIDE[s]
                seen[s].append((float(n @ v_rel) / speed, speed))
        return True

    swim("crawl", 6.0, layers="basic", control_hook=hook)
    for s in "lr":
        a = np.asarray(seen[s])
        assert len(a) > 50
        assert (a[:, 0] * a[:, 1] ** 2).sum() / (a[:, 1] ** 2).sum() < -0.4, s


def test_tables_record_the_continuous_rules(tmp_path):
    st = load_stroke("crawl")
    t = cyc.load_table(st, layers="all")
    assert t.provenance["config"]["hand_rules"] == calibration_settings()
    # a table made with other hand-rule settings: its "all" table is stale, its
    # "cycle" table (no hand rules) is not
    d = json.loads(cyc.table_path(st).read_text())
    d["provenance"]["config"]["hand_rules"] = {**calibration_settings(), "palm_gain": 0.3}
    p = tmp_path / "crawl.cycle.json"
    p.write_text(json.dumps(d))
    with pytest.raises(DataFileError, match="recalibrate"):
        cyc.load_table(st, p, layers="all")
    cyc.load_table(st, p, layers="cycle")


def test_continuous_layer_follows_the_crawls_figure_of_eight_closer():
    # the ordering on the scenario's 5 m loops (62.8 m, 90 s): measured mean
    # distance from the path 0.18 m with basic + per-cycle, 0.09 m with all layers (0.96
    # m without the speed demand from the aim's curvature); the margin asked, 0.04 m, is
    # under half the measured gap
    def mean(layers):
        r = swim("crawl", 90.0, target=figure_eight(5.0), layers=layers)
        m = _metrics(r)
        assert m["path_completed_fraction"] == 1.0
        return m["distance_to_target_mean_m"]
    assert mean("all") < mean("cycle") - 0.04
