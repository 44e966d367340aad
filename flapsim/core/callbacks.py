"""The one process-wide ``mjcb_passive`` dispatcher.

MuJoCo has a single global passive-force callback. flapsim installs exactly one and
routes each call to the force *providers* registered for the ``(model, data)`` being
stepped, so different models can be stepped alternately in one process, each feeling
only its own forces.

Two kinds of provider:

* **compiled** (:class:`CompiledProvider`): a numba kernel plus the arrays it reads.
  When every registered provider is compiled, the installed callback is itself a
  numba ``cfunc`` that MuJoCo calls directly: no Python runs per step at all. It finds
  its arrays through a table of raw addresses; the dispatcher keeps every array alive
  while it is registered.
* **Python** callables ``f(model, data)`` that *add* to ``data.qfrc_passive``. While
  any is registered the installed callback is a Python trampoline (a few microseconds
  per call) that runs the compiled kernels through the same ``cfunc`` first.

Compiled providers add body wrenches about the world origin (see
:mod:`flapsim.core.wrench`); the dispatcher maps the sum of them to ``qfrc_passive``
once per call. A kernel returns a status code; non-zero codes, and non-finite
wrenches (which are then not applied), are recorded and raised by :meth:`check`
with the provider named. An exception in a Python provider surfaces from
``mj_step`` as :class:`~flapsim.core.errors.ProviderError` naming the provider.

MuJoCo facts this relies on: the callback runs inside every ``mj_forward`` (so 4x per
step with RK4) and is skipped entirely when both springs and dampers are disabled
(``<flag passive="disable"/>`` / ``mjDSBL_SPRING|mjDSBL_DAMPER``); compiling a model
while a Python callback is installed raises, so :func:`flapsim.core.loading.load_model`
suspends the dispatcher around compilation.
"""

from __future__ import annotations

import ctypes
import itertools
import logging
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numba import carray, cfunc, types

from flapsim.core.errors import InputError, ProviderError
from flapsim.core.native import ptr_f64, ptr_i64, voidptr_to_int
from flapsim.core.wrench import map_wrenches

log = logging.getLogger(__name__)

MAX_DATA = 64  # (model, data) pairs with providers at once
MAX_PROVIDERS = 8  # compiled providers per data
MAX_ARGS = 48  # arrays per compiled kernel
_ROW = 3 + 2 * MAX_ARGS
_HDR = 13  # header fields used (see _fill_header)

# Status codes written by the compiled callback.
STATUS_OK = 0
STATUS_NONFINITE = 1


@dataclass(frozen=True)
class KernelSpec:
    """A compiled force kernel: ``fn(w, *arrays) -> int`` with typed 1-D array args.

    ``signature`` has one letter per array after ``w``: ``f`` float64, ``i`` int64.
    ``w`` is the flat (nbody*6) wrench accumulator about the world origin.
    """

    name: str
    fn: Callable
    signature: str


_KERNELS: dict[str, KernelSpec] = {}


def register_kernel(name: str, fn: Callable, signature: str) -> None:
    """Make a numba kernel available to compiled providers (call at import time)."""
    if set(signature) - {"f", "i"} or len(signature) > MAX_ARGS:
        raise ValueError(f"kernel {name}: signature must be <= {MAX_ARGS} letters of 'f'/'i'")
    _KERNELS[name] = KernelSpec(name, fn, signature)
    DISPATCHER._kernels_changed()


class CompiledProvider:
    """Base class for providers whose per-step work is a registered numba kernel.

    Subclasses set ``kernel`` (a name given to :func:`register_kernel`) and implement
    :meth:`arrays`, returning the 1-D contiguous float64/int64 arrays the kernel takes,
    in order. Arrays must stay the same objects while registered (update in place).
    """

    kernel: str = ""
    name: str = "compiled provider"

    def arrays(self, model: mujoco.MjModel, data: mujoco.MjData) -> Sequence[np.ndarray]:
        raise NotImplementedError


PythonProvider = Callable[[mujoco.MjModel, mujoco.MjData], None]


def time_view(data: mujoco.MjData) -> np.ndarray:
    """A length-1 float64 array aliasing ``data->time`` (so compiled code sees sim time)."""
    off = _time_offset(data)
    arr = np.ctypeslib.as_array((ctypes.c_double * 1).from_address(data._address + off))
    return arr


_TIME_OFFSET: int | None = None


def _time_offset(data: mujoco.MjData) -> int:
    """Byte offset of ``time`` in ``mjData`` (a constant of the MuJoCo build), found once.

    The bindings expose no struct offsets, so set a sentinel time and find it; the
    result is verified on every use with a second value.
    """
    global _TIME_OFFSET
    saved = data.time
    try:
        if _TIME_OFFSET is None:
            data.time = 7.4211321e-5  # unlikely bit pattern
            # small blocks: the scan stops at most 512 bytes past `time`, well inside the
            # struct (hundreds of pointer fields follow it), so it never reads unmapped memory
            step = 64
            for start in range(0, 1 << 17, step):
                block = np.ctypeslib.as_array(
                    (ctypes.c_double * step).from_address(data._address + 8 * start)
                )
                hits = np.nonzero(block == data.time)[0]
                if hits.size:
                    _TIME_OFFSET = 8 * (start + int(hits[0]))
                    break
            else:  # pragma: no cover - would need a very different MuJoCo
                raise RuntimeError("could not locate mjData.time")
        data.time = 3.1622776e-3
        probe = ctypes.c_double.from_address(data._address + _TIME_OFFSET).value
        if probe != data.time:  # pragma: no cover
            raise RuntimeError("mjData.time offset check failed")
    finally:
        data.time = saved
    return _TIME_OFFSET


@dataclass
class _Entry:
    model: mujoco.MjModel
    data: mujoco.MjData
    index: int
    compiled: list[tuple[int, CompiledProvider, list[np.ndarray]]] = field(default_factory=list)
    python: list[tuple[int, str, PythonProvider]] = field(default_factory=list)
    keep: list[np.ndarray] = field(default_factory=list)  # header arrays kept alive


class Registration:
    """Handle for one registered provider; also a context manager that unregisters."""

    def __init__(self, dispatcher: PassiveDispatcher, key: int, token: int, name: str):
        self._dispatcher = dispatcher
        self._key = key
        self._token = token
        self.name = name
        self.active = True

    def remove(self) -> None:
        if self.active:
            self._dispatcher._remove(self._key, self._token)
            self.active = False

    def __enter__(self) -> Registration:
        return self

    def __exit__(self, *exc: object) -> None:
        self.remove()


class PassiveDispatcher:
    """Routes MuJoCo's global passive callback to per-(model, data) providers."""

    def __init__(self) -> None:
        self._table = np.zeros((MAX_DATA, MAX_PROVIDERS + 1, _ROW), dtype=np.int64)
        self._entries: dict[int, _Entry] = {}
        self._tokens = itertools.count(1)
        self._cfunc = None
        self._cfunc_kernels: tuple[str, ...] = ()
        self._installed: object = None
        self._suspended = 0
        self._lock = threading.RLock()

    # -- registration -------------------------------------------------------------
    def register(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        provider: CompiledProvider | PythonProvider,
        name: str | None = None,
    ) -> Registration:
        """Call ``provider`` whenever MuJoCo computes passive forces for ``data``."""
        if not isinstance(model, mujoco.MjModel) or not isinstance(data, mujoco.MjData):
            raise InputError("register(model, data, provider) needs a mujoco.MjModel and MjData")
        if data.qfrc_passive.shape[0] != model.nv:
            raise InputError("data was not made from this model (nv differs)")
        with self._lock:
            key = data._address
            entry = self._entries.get(key)
            if entry is None:
                used = {e.index for e in self._entries.values()}
                free = [i for i in range(MAX_DATA) if i not in used]
                if not free:
                    raise InputError(f"more than {MAX_DATA} simulations with force providers at once")
                entry = _Entry(model, data, free[0])
                self._entries[key] = entry
            elif entry.model is not model:
                raise InputError("this MjData is already registered with a different MjModel")
            token = next(self._tokens)
            if isinstance(provider, CompiledProvider):
                if provider.kernel not in _KERNELS:
                    raise InputError(f"provider {provider.name!r}: kernel {provider.kernel!r} unknown")
                if len(entry.compiled) >= MAX_PROVIDERS:
                    raise InputError(f"more than {MAX_PROVIDERS} compiled providers on one MjData")
                arrays = [np.ascontiguousarray(a) for a in provider.arrays(model, data)]
                spec = _KERNELS[provider.kernel]
                _check_arrays(provider.name, spec, arrays)
                label = name or provider.name
                entry.compiled.append((token, provider, arrays))
            else:
                if not callable(provider):
                    raise InputError("a provider must be a CompiledProvider or a callable(model, data)")
                label = name or getattr(provider, "name", None) or getattr(
                    provider, "__name__", "python provider"
                )
                entry.python.append((token, label, provider))
            self._refresh()
            return Registration(self, key, token, label)

    def _remove(self, key: int, token: int) -> None:
        with self._lock:
            entry = self._entries.get(key)
            if entry is None:
                return
            entry.compiled = [c for c in entry.compiled if c[0] != token]
            entry.python = [p for p in entry.python if p[0] != token]
            if not entry.compiled and not entry.python:
                del self._entries[key]
            self._refresh()

    def clear(self) -> None:
        """Unregister everything and uninstall the callback."""
        with self._lock:
            self._entries.clear()
            self._refresh()

    def providers(self, data: mujoco.MjData) -> list[str]:
        """Names of the providers registered for ``data``, compiled first."""
        entry = self._entries.get(data._address)
        if entry is None:
            return []
        return [p.name for _, p, _ in entry.compiled] + [n for _, n, _ in entry.python]

    # -- status -------------------------------------------------------------------
    def check(self, data: mujoco.MjData) -> None:
        """Raise :class:`ProviderError` if a compiled provider reported a problem."""
        entry = self._entries.get(data._address)
        if entry is None:
            return
        rows = self._table[entry.index]
        if rows[0, 11] != STATUS_OK:
            rows[0, 11] = STATUS_OK
            names = ", ".join(p.name for _, p, _ in entry.compiled)
            raise ProviderError(
                f"non-finite force from provider(s) {names} at t={data.time:.4f} s: the state "
                "diverged (check for NaN inputs, or lower the timestep)"
            )
        for slot, (_, provider, _) in enumerate(entry.compiled):
            code = rows[1 + slot, 2]
            if code != STATUS_OK:
                rows[1 + slot, 2] = STATUS_OK
                raise ProviderError(
                    f"passive force provider {provider.name!r} reported status {code} at "
                    f"t={data.time:.4f} s"
                )

    @contextmanager
    def frozen(self) -> Iterator[None]:
        """Within the block no registration changes the table the compiled callback reads:
        ``register`` and ``remove`` from other threads wait. For a thread that steps a
        simulation while another may register or remove providers (the table is rewritten
        whole on every change; a callback reading it half-written would find no forces, or
        worse)."""
        with self._lock:
            yield

    # -- installation -------------------------------------------------------------
    @contextmanager
    def suspended(self) -> Iterator[None]:
        """Uninstall the callback temporarily (MuJoCo refuses to compile models while a
        Python callback is set)."""
        with self._lock:
            self._suspended += 1
            self._install(None)
        try:
            yield
        finally:
            with self._lock:
                self._suspended -= 1
                self._refresh()

    def _kernels_changed(self) -> None:
        if self._cfunc is not None and tuple(_KERNELS) != self._cfunc_kernels:
            self._cfunc = None
            if self._entries:
                self._refresh()

    def _refresh(self) -> None:
        self._table[:] = 0
        any_python = False
        for entry in self._entries.values():
            any_python |= bool(entry.python)
            if entry.compiled:
                self._fill(entry)
        if self._suspended or not self._entries:
            self._install(None)
            return
        has_compiled = any(e.compiled for e in self._entries.values())
        if has_compiled and self._cfunc is None:
            self._cfunc = _build_cfunc(self._table.ctypes.data)
            self._cfunc_kernels = tuple(_KERNELS)
        if any_python:
            self._install(self._python_trampoline)
        else:
            self._install(self._cfunc.ctypes)

    def _install(self, callback: object) -> None:
        if callback is self._installed:
            return
        mujoco.set_mjcb_passive(callback)
        self._installed = callback

    def _fill(self, entry: _Entry) -> None:
        m, d = entry.model, entry.data
        if not entry.keep:
            w = np.zeros(6 * m.nbody)
            ints = [np.ascontiguousarray(a, dtype=np.int64) for a in
                    (m.body_parentid, m.body_rootid, m.dof_bodyid)]
            entry.keep = [w, *ints, d.cdof.reshape(-1), d.subtree_com.reshape(-1), d.qfrc_passive,
                          time_view(d)]
        w, parent, root, dofbody, cdof, scom, qfrc, tview = entry.keep
        hdr = self._table[entry.index, 0]
        hdr[:_HDR] = (
            d._address, len(entry.compiled), m.nbody, m.nv, w.ctypes.data, parent.ctypes.data,
            root.ctypes.data, dofbody.ctypes.data, cdof.ctypes.data, scom.ctypes.data,
            qfrc.ctypes.data, STATUS_OK, tview.ctypes.data,
        )
        names = list(_KERNELS)
        for slot, (_, provider, arrays) in enumerate(entry.compiled):
            row = self._table[entry.index, 1 + slot]
            row[0] = names.index(provider.kernel)
            row[1] = 1
            row[2] = STATUS_OK
            for k, a in enumerate(arrays):
                row[3 + 2 * k] = a.ctypes.data
                row[4 + 2 * k] = a.size

    def _python_trampoline(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        entry = self._entries.get(d._address)
        if entry is None:
            return
        if entry.compiled:
            self._cfunc.ctypes(m._address, d._address)
        for _, label, provider in entry.python:
            try:
                provider(m, d)
            except ProviderError:
                raise
            except Exception as exc:
                raise ProviderError(
                    f"passive force provider {label!r} failed at t={d.time:.4f} s: "
                    f"{type(exc).__name__}: {exc}"
                ) from exc


def _check_arrays(name: str, spec: KernelSpec, arrays: list[np.ndarray]) -> None:
    if len(arrays) != len(spec.signature):
        raise InputError(
            f"provider {name!r}: kernel {spec.name} takes {len(spec.signature)} arrays, "
            f"got {len(arrays)}"
        )
    for k, (a, letter) in enumerate(zip(arrays, spec.signature, strict=True)):
        want = np.float64 if letter == "f" else np.int64
        if a.dtype != want or a.ndim != 1:
            raise InputError(
                f"provider {name!r}: array {k} must be 1-D {np.dtype(want).name}, "
                f"got {a.ndim}-D {a.dtype}"
            )


def _build_cfunc(table_address: int):
    """Generate and compile the C callback for the kernels registered now.

    The table address is baked in as a constant, so this compiles once per process
    (~0.5 s); the kernels themselves come from numba's on-disk cache.
    """
    names = list(_KERNELS)
    lines = [
        "def _cb(mp, dp):",
        f"    tbl = carray(ptr_i64({table_address}), ({MAX_DATA}, {MAX_PROVIDERS + 1}, {_ROW}))",
        "    key = voidptr_to_int(dp)",
        f"    for e in range({MAX_DATA}):",
        "        hdr = tbl[e, 0]",
        "        if hdr[0] != key:",
        "            continue",
        "        nbody = hdr[2]",
        "        w = carray(ptr_f64(hdr[4]), 6 * nbody)",
        "        for k in range(6 * nbody):",
        "            w[k] = 0.0",
        "        for p in range(hdr[1]):",
        "            row = tbl[e, 1 + p]",
        "            if row[1] == 0:",
        "                continue",
        "            kind = row[0]",
    ]
    glb = {
        "carray": carray, "ptr_f64": ptr_f64, "ptr_i64": ptr_i64,
        "voidptr_to_int": voidptr_to_int, "map_wrenches": map_wrenches,
    }
    for kind, name in enumerate(names):
        spec = _KERNELS[name]
        glb[f"K{kind}"] = spec.fn
        args = []
        for k, letter in enumerate(spec.signature):
            ptr = "ptr_f64" if letter == "f" else "ptr_i64"
            args.append(f"carray({ptr}(row[{3 + 2 * k}]), row[{4 + 2 * k}])")
        kw = "if" if kind == 0 else "elif"
        lines += [
            f"            {kw} kind == {kind}:",
            f"                st = K{kind}(w, {', '.join(args)})",
            "                if st != 0:",
            "                    row[2] = st",
        ]
    lines += [
        "        st = map_wrenches(w, nbody, hdr[3], carray(ptr_i64(hdr[5]), nbody),",
        "                          carray(ptr_i64(hdr[6]), nbody), carray(ptr_i64(hdr[7]), hdr[3]),",
        "                          carray(ptr_f64(hdr[8]), 6 * hdr[3]), carray(ptr_f64(hdr[9]), 3 * nbody),",
        "                          carray(ptr_f64(hdr[10]), hdr[3]))",
        "        if st != 0:",
        "            hdr[11] = st",
        "        return",
    ]
    ns: dict = {}
    exec(compile("\n".join(lines), "<flapsim passive callback>", "exec"), glb, ns)  # noqa: S102
    log.info("compiling the passive callback for kernels %s", names)
    return cfunc(types.void(types.voidptr, types.voidptr))(ns["_cb"])


#: The process-wide dispatcher.
DISPATCHER = PassiveDispatcher()


def register(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    provider: CompiledProvider | PythonProvider,
    name: str | None = None,
) -> Registration:
    """Shorthand for ``DISPATCHER.register``."""
    return DISPATCHER.register(model, data, provider, name)
