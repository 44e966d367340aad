"""The next wingbeat's reference simulated on a second core (flapsim.bird.control.lookahead): the
flight must be the same to the bit, a look-ahead taken only for exactly its own request, and
the callback table never rewritten under a stepping thread."""

import dataclasses
import threading
import time
from concurrent import futures

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control import controller as C
from flapsim.bird.control.lookahead import ReferenceLookahead, _fly_frozen
from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.bird.tasks.flight_tasks import PushSpec, Task, fly_task
from flapsim.bird.tasks.path_shapes import inclined_circle
from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import InputError
from flapsim.fluid.flow import Gust, PythonField

#: The look-ahead simulates the paper's S0 (on the flight, at its own rate) ahead; every
#: correction simulated, so that each wingbeat has a best-so-far before its last correction
PAPER_S0 = {"reference_hz": 0.0, "refine_stop": 0.0}


def test_the_lookahead_flies_the_same_flight_to_the_bit_in_a_gust_and_a_push():
    # a turn (the corrections at work), a side gust (the flow shared with the copy, read at
    # the copy's own time) and a push (the pushed wingbeat's end is no candidate's)
    task = Task(inclined_circle(6.0, 0.0, 0.5), flow=(Gust((0.0, 1.0, 0.0), 2.0, 0.3, 0.6),),
                pushes=(PushSpec(0.55, 4.0, "left"),), max_wingbeats=14)
    off = fly_task(task, lookahead="off", **PAPER_S0)
    on = fly_task(task, lookahead="on", **PAPER_S0)
    assert off.lookahead is None
    assert len(on.positions) == len(off.positions) == 15
    # identical, not close: the copy steps the same model at the same step from the same state
    np.testing.assert_array_equal(on.positions, off.positions)
    np.testing.assert_array_equal(on.quats, off.quats)
    hits, misses = on.lookahead
    # every wingbeat's reference is either taken or simulated on the spot
    assert hits + misses == 14
    # on the spot at least: the first wingbeat (nothing ahead) and the one after the push
    assert misses >= 2
    # and otherwise ahead where a correction before the last was flown (when the last one is,
    # its continuation is simulated on the spot: nothing would run beside it); how many is
    # counted exactly in the next test
    assert hits >= 1


def _flown_candidates(monkeypatch, ctl, target, wingbeats):
    """Fly ``wingbeats`` under ``ctl`` from the cruise start; per wingbeat (its step, which of
    the simulated candidates was flown, how many were simulated). With a look-ahead every one
    started is waited for before the next wingbeat, so that which are taken does not depend
    on the machine's load."""
    ends = []
    fly = cycle.fly_cycle

    def recorded(fl, *a, **kw):
        e = fly(fl, *a, **kw)
        if fl is ctl.flight:  # not the look-ahead's copy
            ends.append(e)
        return e

    monkeypatch.setattr(C.cycle, "fly_cycle", recorded)
    C.start_cruise(ctl.flight, ctl.P0, roll_deg=15.0)
    ctl.reset()
    out = []
    for _ in range(wingbeats):
        if ctl.lookahead is not None:
            futures.wait([f for _, f in ctl.lookahead._pending])
        n0 = len(ends)
        step = ctl.choose(target)
        cands = [e for e in ends[n0:] if e is not step.reference]
        out.append((step, [i for i, e in enumerate(cands) if e is step.end][0], len(cands)))
    monkeypatch.undo()
    return out


def test_the_lookahead_flies_the_chosen_wingbeats_to_the_bit_and_takes_every_one_it_can(
        flight, monkeypatch):
    ctl = C.load_controller(flight, lookahead="off", **PAPER_S0)
    target = CruiseTarget(trim_of_base_flight(flight, ctl.P0), altitude=10.0, heading=0.4)
    off = _flown_candidates(monkeypatch, ctl, target, 8)
    target.reset()
    ctl.lookahead = C.make_lookahead(flight, "on", ctl.refine, "simulate")
    on = _flown_candidates(monkeypatch, ctl, target, 8)
    for (a, ia, na), (b, ib, nb) in zip(off, on, strict=True):
        # the same candidates simulated and the same one flown, to the bit
        assert (ia, na) == (ib, nb) == (ia, ctl.refine + 1)
        np.testing.assert_array_equal(a.P, b.P)
        np.testing.assert_array_equal(a.end.snapshot.physics, b.end.snapshot.physics)
        np.testing.assert_array_equal(a.reference.snapshot.physics, b.reference.snapshot.physics)
    # a wingbeat's reference was ahead exactly when the last wingbeat flew a candidate before
    # its last correction (the turn flies both kinds)
    ahead = sum(i < n - 1 for _, i, n in off[:-1])
    assert 0 < ahead < len(off) - 1
    assert (ctl.lookahead.hits, ctl.lookahead.misses) == (ahead, len(off) - ahead)


@pytest.fixture()
def flight():
    fl = DoveFlight(Dove.load())
    yield fl
    fl.close()


def _start(fl):
    ctl = C.load_controller(fl)
    C.start_cruise(fl, ctl.P0)
    return ctl, cycle.snapshot(fl)


def test_a_lookahead_is_taken_only_for_exactly_its_own_request(flight):
    ctl, snap = _start(flight)
    la = ReferenceLookahead(flight)
    P = ctl.P0.copy()
    la.submit(snap, P, flight.ref)
    end = la.take(snap, P)
    own = cycle.fly_cycle(flight, snap, P, flight.ref)
    np.testing.assert_array_equal(end.snapshot.physics, own.snapshot.physics)
    np.testing.assert_array_equal(end.S, own.S)
    assert (la.hits, la.misses) == (1, 0)
    # one parameter one ulp off: not the request simulated
    Q = P.copy()
    Q[3] = np.nextafter(Q[3], np.inf)
    la.submit(snap, P, flight.ref)
    assert la.take(snap, Q) is None
    # nothing ahead at all
    assert la.take(snap, P) is None
    assert (la.hits, la.misses) == (1, 2)


def test_a_lookahead_is_not_taken_once_the_flow_has_changed(flight):
    # the viewer's gust key re-packs the flow in place between wingbeats: the copy shares it
    ctl, snap = _start(flight)
    la = ReferenceLookahead(flight)
    la.submit(snap, ctl.P0, flight.ref)
    la._pending[0][1].result()  # simulated in the old air
    flight.flow.set_uniform((0.0, 1.0, 0.0))
    assert la.take(snap, ctl.P0) is None
    assert la.misses == 1


def test_the_lookahead_setting_is_an_error_where_it_cannot_run(flight, monkeypatch):
    with pytest.raises(InputError, match="refine = 1 or more"):
        C.make_lookahead(flight, "on", 0, "simulate")
    with pytest.raises(InputError, match="--predict simulate"):
        C.make_lookahead(flight, "on", 2, "coarse")
    with pytest.raises(InputError, match="lookahead must be one of"):
        C.make_lookahead(flight, "yes", 2, "simulate")
    assert C.make_lookahead(flight, "off", 2, "simulate") is None
    # auto: quietly off where it cannot run, or on a single core
    assert C.make_lookahead(flight, "auto", 0, "simulate") is None
    monkeypatch.setattr(C, "usable_cores", lambda: 1)
    assert C.make_lookahead(flight, "auto", 2, "simulate") is None
    monkeypatch.setattr(C, "usable_cores", lambda: 2)
    assert isinstance(C.make_lookahead(flight, "auto", 2, "simulate"), ReferenceLookahead)
    assert C.load_controller(flight, lookahead="on", reference_hz=0.0).lookahead is not None
    # S0 on a coarser copy (the rigid dove's default): nothing to simulate ahead on the flight
    with pytest.raises(InputError, match="reference_hz = 0"):
        C.load_controller(flight, lookahead="on")
    assert C.load_controller(flight, lookahead="auto").lookahead is None


def test_a_python_flow_field_refuses_the_lookahead():
    fl = DoveFlight(Dove.load(), flow=(PythonField(lambda p, t: np.zeros_like(p)),))
    try:
        with pytest.raises(InputError, match="Python flow field"):
            C.make_lookahead(fl, "on", 2, "simulate")
        assert C.make_lookahead(fl, "auto", 2, "simulate") is None
    finally:
        fl.close()


def test_registrations_wait_while_a_thread_steps_under_the_frozen_table():
    m = mujoco.MjModel.from_xml_string("<mujoco><worldbody><body><freejoint/><geom size='.1'/>"
                                       "</body></worldbody></mujoco>")
    d = mujoco.MjData(m)
    done = threading.Event()

    def register():
        DISPATCHER.register(m, d, lambda m_, d_: None, "probe").remove()
        done.set()

    with DISPATCHER.frozen():
        t = threading.Thread(target=register)
        t.start()
        time.sleep(0.3)
        # the other thread is held at the table's lock, not finished
        assert not done.is_set()
    t.join(10.0)
    assert done.is_set()


def test_closing_the_flight_waits_for_a_running_lookahead():
    fl = DoveFlight(Dove.load())
    ctl, snap = _start(fl)
    la = ReferenceLookahead(fl)
    la.submit(snap, ctl.P0, fl.ref)
    fut = la._pending[0][1]
    fl.close()  # the look-ahead's close runs first: its wingbeat ends before the forces go
    assert fut.done()
    assert la._pool is None


def test_a_copy_stepped_in_another_thread_sums_its_own_induced_flow():
    # the induced flow sums each wing's force into scratch before turning it into downwash:
    # a flight and its copy stepping at once in two threads must each sum only their own
    # (a shared sum gave each part of the other's lift: flights under the look-ahead
    # differed from run to run)
    from flapsim.bird.flight.dove_flight import CRUISE
    from flapsim.bird.flight.wingbeat import p0, with_tail_bias

    fl = DoveFlight(Dove.load(induced=True), table=CRUISE.table)
    try:
        P = with_tail_bias(p0(), CRUISE.tail_bias_deg)
        fl.reset(dataclasses.replace(CRUISE, speed=8.5), P)
        snap_a = cycle.snapshot(fl)
        fl.reset(dataclasses.replace(CRUISE, speed=6.0, pitch_deg=25.0), P)
        snap_b = cycle.snapshot(fl)
        twin = fl.twin(None)
        # apart first: each its own end, one after the other
        alone_a = cycle.fly_cycle(fl, snap_a, P, fl.ref).snapshot.physics
        alone_b = cycle.fly_cycle(twin, snap_b, P, fl.ref).snapshot.physics
        assert not np.array_equal(alone_a, alone_b)  # two different flights, or the test is blind
        with futures.ThreadPoolExecutor(max_workers=1) as pool:
            for _ in range(3):  # two cores step both at once; three tries, each a wingbeat long
                fut = pool.submit(_fly_frozen, twin, snap_b, P, fl.ref)
                a = cycle.fly_cycle(fl, snap_a, P, fl.ref).snapshot.physics
                np.testing.assert_array_equal(fut.result().snapshot.physics, alone_b)
                np.testing.assert_array_equal(a, alone_a)
    finally:
        fl.close()
    # and where the cores are too busy to overlap the threads: each registration's scratch
    # is its own array
    forces = fl.aero
    d1, d2 = mujoco.MjData(fl.model), mujoco.MjData(fl.model)
    assert forces.arrays(fl.model, d1)[-1] is not forces.arrays(fl.model, d2)[-1]
