"""The regression's two options for requests far from cruise: clipping a request to what
the database's samples did (``clip_request``), and choosing neighbours by the wingbeat's
start state as well as by dS (``context_weight``); checked against values known in
closed form."""

import numpy as np
import pytest

from flapsim.bird.control.regression import DEFAULT_CLIP_REQUEST, Regressor
from flapsim.core.errors import InputError

N = 4000
DS = np.random.default_rng(7).uniform(-1.0, 1.0, (N, 8))
A = np.random.default_rng(8).standard_normal((8, 5))


def test_a_request_is_clipped_to_the_quantiles_of_the_samples():
    # dP linear in dS: LWLR reproduces it exactly, so the answer shows which dS was used
    dP = DS @ A
    plain = Regressor(DS, dP, k=100, method="lwlr", ridge=1e-9)
    clip = Regressor(DS, dP, k=100, method="lwlr", ridge=1e-9, clip_request=0.02)
    # uniform on [-1, 1]: the 2 % and 98 % quantiles are -0.96 and 0.96 (sampling error ~0.004)
    np.testing.assert_allclose(clip.dS_lo, -0.96, atol=0.015)
    np.testing.assert_allclose(clip.dS_hi, 0.96, atol=0.015)
    far = np.array([5.0, -5.0, 0.3, 0, 0, 0, 0, -0.2])
    np.testing.assert_allclose(clip.predict(far), np.clip(far, clip.dS_lo, clip.dS_hi) @ A, atol=1e-6)
    # without the clip the linear model is extrapolated to 5 and then clipped per wingbeat
    # parameter to the samples' extremes: another wingbeat
    assert np.max(np.abs(plain.predict(far) - clip.predict(far))) > 0.5
    # inside the samples' range the clip changes nothing
    for x in np.random.default_rng(9).uniform(-0.9, 0.9, (5, 8)):
        np.testing.assert_array_equal(clip.predict(x), plain.predict(x))


def test_the_start_state_separates_samples_that_dS_alone_mixes():
    # two kinds of samples with the same dS: from states near 0 a wingbeat dP = A dS gives
    # dS, from states near 3 (in every component; think of a steep bank) the opposite one
    rng = np.random.default_rng(10)
    S = np.where(rng.random(N)[:, None] < 0.5, 0.0, 3.0) + 0.1 * rng.standard_normal((N, 8))
    sign = np.where(S[:, 0] < 1.5, 1.0, -1.0)
    dP = sign[:, None] * (DS @ A)
    x = np.array([0.3, -0.2, 0.1, 0.0, 0.2, -0.1, 0.0, 0.1])
    mixed = Regressor(DS, dP, k=100, method="lwlr", ridge=1e-9)
    cond = Regressor(DS, dP, k=100, method="lwlr", ridge=1e-9, context=S, context_weight=1.0)
    assert cond.conditioned and not mixed.conditioned
    # dS alone: the neighbours are half of each kind, and the fit answers neither
    assert np.linalg.norm(mixed.predict(x) - x @ A) > 0.5 * np.linalg.norm(x @ A)
    for s0, want in ((np.zeros(8), x @ A), (np.full(8, 3.0), -(x @ A))):
        np.testing.assert_allclose(cond.predict(x, s0), want, atol=0.02 * np.linalg.norm(want))
    # k-NN too picks its neighbours from the right kind (its average is near, not at, x A)
    knn = Regressor(DS, dP, k=20, method="knn", context=S, context_weight=1.0)
    for s0, want in ((np.zeros(8), x @ A), (np.full(8, 3.0), -(x @ A))):
        assert np.linalg.norm(knn.predict(x, s0) - want) < 0.5 * np.linalg.norm(want)


def test_bad_options_are_one_line_errors():
    dP = DS @ A
    for kw, fragment in (({"clip_request": 0.5}, "request clip"), ({"clip_request": -0.1}, "request clip"),
                         ({"context_weight": -1.0}, "state weight"),
                         ({"context_weight": 1.0}, "needs each sample's start state"),
                         ({"context_weight": 1.0, "context": DS[:10]}, "start states must be")):
        with pytest.raises(InputError) as e:
            Regressor(DS, dP, **kw)
        assert fragment in str(e.value) and "\n" not in str(e.value)
    cond = Regressor(DS, dP, context=DS, context_weight=1.0)
    with pytest.raises(InputError, match="needs the current state"):
        cond.predict(np.zeros(8))
    with pytest.raises(InputError, match="needs the current state"):
        cond.predict(np.zeros(8), np.full(8, np.nan))


def test_eval_and_fly_options_reach_the_controller(monkeypatch):
    """The configuration's clip_request / state_weight: the controller a scenario flies has
    them, and a conditioned regression is given the state the wingbeat starts from."""
    import flapsim.bird.tasks.flight_tasks as tasks
    import flapsim.scenarios.flight as flight_scenarios
    from flapsim.bird.control.config import ControllerConfig
    from flapsim.bird.control.controller import start_cruise
    from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
    from flapsim.bird.flight import cycle
    from flapsim.bird.tasks import path_shapes as paths
    from flapsim.scenarios import EvalOptions
    from flapsim.scenarios.flight import _fly_task

    seen = {}
    real_build_flight = tasks.build_flight

    def fake_fly_task(task, db=None, method="lwlr", k=None, record=False, controller=None,
                      mirror=True, **options):
        # the controller fly_task would fly: built from what the scenario passed on
        fl, seen["ctl"] = real_build_flight(task, db, method, k, mirror, **options)
        fl.close()
        return "flown"

    monkeypatch.setattr(flight_scenarios, "fly_task", fake_fly_task)
    task = tasks.Task(paths.straight(20.0))
    tuned = ControllerConfig(clip_request=0.02, state_weight=0.5)
    assert _fly_task(task, EvalOptions(controller=tuned), record=False) == "flown"
    ctl = seen["ctl"]
    reg = ctl.regressor
    assert reg.clip_request == 0.02 and reg.context_weight == 0.5 and reg.conditioned
    assert reg.n == len(reg.context) and reg.dS_lo is not None
    # one controlled wingbeat: the regression sees the start state, not P0's end
    from flapsim.bird.body.model import Dove
    from flapsim.bird.control.controller import load_controller
    from flapsim.bird.flight.dove_flight import DoveFlight

    fl = DoveFlight(Dove.load())
    try:
        assert load_controller(fl).regressor.clip_request == DEFAULT_CLIP_REQUEST
        ctl = load_controller(fl, state_weight=0.5)
        reg = ctl.regressor
        trim = trim_of_base_flight(fl, ctl.P0)
        start_cruise(fl, ctl.P0, roll_deg=3.0)
        cycle.fly_cycle(fl, None, ctl.P0)  # a start with the joints and feathers in motion
        S_start = fl.reduced_state()
        got = {}
        predict = reg.predict

        def spy(x, s=None):
            got["s"] = s
            return predict(x, s)

        reg.predict = spy
        step = ctl.choose(CruiseTarget(trim, altitude=float(fl.data.qpos[2])))
        np.testing.assert_array_equal(got["s"], S_start)
        assert np.max(np.abs(step.reference.S - S_start)) > 1e-3  # P0's end is another state
    finally:
        fl.close()


@pytest.mark.parametrize("cmd, line, fragment", [
    ("eval", "clip_request = 0.5", "clip_request must be"),
    ("eval", "clip_request = nan", "controller.clip_request is nan, a non-finite number"),
    ("eval", "state_weight = -1", "state_weight must be"),
    ("fly", "clip_request = -0.1", "clip_request must be"),
])
def test_cli_regression_options_bad_values(capsys, tmp_path, cmd, line, fragment):
    from flapsim.cli.main import main

    config = tmp_path / "bad.toml"
    config.write_text(f"[controller]\n{line}\n")
    code = main([cmd, *(["--controller", "learned"] if cmd == "fly" else []), "--config", str(config)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and fragment in err and "\n" not in err, err


def test_cli_defaults_are_the_library_default():
    from flapsim.bird.control.config import ControllerConfig

    for feathers in ("rigid", "modal"):
        c = ControllerConfig.for_dove(feathers)
        assert c.clip_request == DEFAULT_CLIP_REQUEST and c.state_weight == 0


def test_the_conditioned_fit_is_affine_in_the_start_state_too():
    # dP linear in dS AND in the start state S: the conditioned LWLR is affine in both, so it
    # reproduces the map exactly (round-off and the 1e-9 ridge only). A fit affine in dS
    # alone would absorb the S term's variation across the neighbourhood into its dS slopes
    # and intercept (measured: off by 0.9), far above the tolerance
    rng = np.random.default_rng(11)
    S = rng.uniform(-1.0, 1.0, (N, 8))
    B = rng.standard_normal((8, 5))
    dP = DS @ A + S @ B
    cond = Regressor(DS, dP, k=100, method="lwlr", ridge=1e-9, context=S, context_weight=1.0)
    for x, s in zip(rng.uniform(-0.5, 0.5, (4, 8)), rng.uniform(-0.5, 0.5, (4, 8)), strict=True):
        np.testing.assert_allclose(cond.predict(x, s), x @ A + s @ B, atol=1e-5)
