"""The path's nearest-point searches cost what their window costs, not what the path's
length costs (a 910 km path took 1 s per search, 133 s for 2 wingbeats), and give the
brute-force search's answers to the bit."""

import numpy as np

from flapsim.bird.tasks.path_control import FlightPath


class _Counted(np.ndarray):
    """The path's samples, counting how many each fancy index or arithmetic reads."""

    read: list[int] = []

    def __getitem__(self, key):
        if isinstance(key, np.ndarray | list):
            _Counted.read.append(int(np.size(key)))
        return np.ndarray.__getitem__(np.asarray(self), key)

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        plain = [np.asarray(x) if isinstance(x, _Counted) else x for x in inputs]
        _Counted.read.append(max(int(np.size(x)) for x in plain))
        return getattr(ufunc, method)(*plain, **kwargs)


def _path(km):
    x = np.linspace(0.0, km * 1000.0, int(km * 10) + 2)
    pts = np.stack([x, 30.0 * np.sin(x / 200.0), 5.0 * np.cos(x / 350.0)], axis=1)
    return FlightPath(pts)


def _brute_closest(path, p, lo, hi):
    s = np.asarray(path._s)
    sel = np.flatnonzero((s >= lo - 1e-9) & (s <= hi + 1e-9))
    d = np.linalg.norm(np.asarray(path._pts)[sel] - p, axis=1)
    return float(s[sel[np.argmin(d)]])


def test_searches_read_their_window_only_and_match_brute_force():
    rng = np.random.default_rng(1)
    path = _path(20.0)  # 20 km: 400,000 samples
    assert len(path._s) > 390_000
    path.distance(path.point(0.0))  # the KD-tree is built once, on the first search
    for name in ("_pts", "_s"):
        object.__setattr__(path, name, getattr(path, name).view(_Counted))
    for _ in range(5):
        s0 = rng.uniform(0.0, path.length - 100.0)
        p = path.point(s0) + rng.normal(0.0, 2.0, 3)
        _Counted.read.clear()
        got = path.closest(p, s0 - 1.0, s0 + 21.0)
        # a 22 m window holds 22 / 0.05 = 440 samples (the samples are ~0.05 m apart; 10 %
        # for the spline's arc length running ahead of its parameter)
        assert _Counted.read and max(_Counted.read) <= 1.1 * 22.0 / 0.05 + 2
        _Counted.read.clear()
        dist = path.distance(p)
        assert max(_Counted.read, default=0) <= 3  # one sample (a KD-tree query)
        assert got == _brute_closest(path, p, s0 - 1.0, s0 + 21.0)
        assert dist == float(np.min(np.linalg.norm(np.asarray(path._pts) - p, axis=1)))
    # outside the path's arc lengths: the sample nearest the window, as before
    assert path.closest(np.zeros(3), path.length + 5.0, path.length + 9.0) == path.length
