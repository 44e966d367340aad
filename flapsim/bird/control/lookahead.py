"""The next wingbeat's reference, simulated on a second core while this wingbeat's
candidates are (:attr:`~flapsim.bird.control.controller.WingbeatController.lookahead`).

Under the simulated corrections (``refine`` N > 0) a controlled wingbeat is N + 2 whole
simulated wingbeats in a row: the reference wingbeat for S0, then the answer and its N
corrections, each needing the one before. The next wingbeat's reference needs only the
wingbeat flown: its start is one candidate's end and its parameters follow from that
candidate's (P0 + carry (P - P0)). So as soon as a candidate is the best so far, its
continuation can be simulated on a copy of the flight (:meth:`DoveFlight.twin` at the
flight's own step: the same forces, flows and plucked feathers) in a worker thread, while
the main thread simulates the next candidate. ``mujoco.rollout`` releases the GIL and the
compiled passive callback runs no Python, so the two use two cores.

The flight is the same to the bit: the next wingbeat takes a look-ahead only when its own
reference request is exactly the one simulated (start state, warm start, hinge memory,
parameters and the flow's primitives, compared byte for byte) and otherwise simulates it
as it would have. What changes is the wall time: when the last correction is not the one
flown, the reference is already there. Only the best-so-far's continuation is worth simulating
(a newer best cancels the older one if it has not started), none after the last correction
(nothing runs beside it here), and one still queued when it is asked for is simulated here
rather than waited for. Each wingbeat still waits for the candidates one after another:
``flapsim bench controller`` reports how many whole wingbeats are simulated per wingbeat flown
(4 with two corrections: at most 1/4 of a bare rollout on one thread, 1/3 on two).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import InputError


def _fly_frozen(fl: DoveFlight, snap: cycle.Snapshot, params: np.ndarray, ref) -> cycle.CycleEnd:
    # the callback table must not be rewritten under this thread's steps (a flight closed or
    # built meanwhile waits for it): :meth:`PassiveDispatcher.frozen`
    with DISPATCHER.frozen():
        return cycle.fly_cycle(fl, snap, params, ref)


def _key(snap: cycle.Snapshot, params: np.ndarray, flow: np.ndarray) -> tuple[bytes, ...]:
    ud = b"" if snap.userdata is None else np.ascontiguousarray(snap.userdata).tobytes()
    return (np.ascontiguousarray(snap.physics).tobytes(),
            np.ascontiguousarray(snap.warmstart).tobytes(), ud,
            np.ascontiguousarray(params, dtype=float).tobytes(),
            np.ascontiguousarray(flow).tobytes())


class ReferenceLookahead:
    """Simulates wingbeats on a same-step copy of ``flight`` in one worker thread and hands
    each back only to an identical request (see the module)."""

    def __init__(self, flight: DoveFlight) -> None:
        if flight.aero.flow.has_python:
            # a Python flow field runs under the GIL every step: nothing to run in parallel,
            # and its provider's scratch is shared between the flight and its copy
            raise InputError("the look-ahead needs a compiled flow (uniform, gust, breeze, "
                             "source, vortex): this flow has a Python field")
        self.flight = flight
        self._twin: DoveFlight | None = None
        self._pool: ThreadPoolExecutor | None = None
        self._pending: list[tuple[tuple[bytes, ...], Future]] = []
        flight._on_close.append(self.close)
        self.hits = 0
        """References taken from the look-ahead."""
        self.misses = 0
        """References simulated on the spot (none was ahead, or none matched)."""

    def _flow(self) -> np.ndarray:
        return self.flight.aero.flow.params

    def submit(self, snap: cycle.Snapshot, params: np.ndarray, ref) -> None:
        """Start simulating wingbeat ``params`` from ``snap`` on the copy (queued behind any
        started before)."""
        if self._twin is None:
            self._twin = self.flight.twin(None)
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="flapsim-lookahead")
        params = np.array(params, dtype=float)
        snap = cycle.Snapshot(snap.physics.copy(), snap.warmstart.copy(),
                              None if snap.userdata is None else snap.userdata.copy())
        # a newer best candidate supersedes the older ones: their continuations can no longer
        # be flown, and one not started yet would hold this one back in the queue
        for _, old in self._pending:
            old.cancel()
        fut = self._pool.submit(_fly_frozen, self._twin, snap, params, ref)
        self._pending.append((_key(snap, params, self._flow()), fut))

    def take(self, snap: cycle.Snapshot, params: np.ndarray) -> cycle.CycleEnd | None:
        """The simulated end of ``params`` from ``snap`` if it was started with exactly these
        (its :class:`~flapsim.core.errors.SimulationError` raised as the flight's own would be),
        else None. Every other look-ahead is dropped."""
        pending, self._pending = self._pending, []
        if not pending:
            self.misses += 1
            return None
        key = _key(snap, params, self._flow())
        hit = None
        for k, fut in pending:
            if hit is None and k == key:
                hit = fut
            else:
                fut.cancel()  # not started yet: never will be; running: finishes unread
        if hit is None or hit.cancel():
            # not simulated, or still queued behind a superseded one: simulated here at once
            # (the same function of the same request, so the same bits) rather than waited for
            self.misses += 1
            return None
        self.hits += 1
        return hit.result()

    def drop(self) -> None:
        """Forget every look-ahead (a new flight, or a state set from outside)."""
        for _, fut in self._pending:
            fut.cancel()
        self._pending = []

    def close(self) -> None:
        """Wait for the worker and let it go (the copy closes with the flight)."""
        self.drop()
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
