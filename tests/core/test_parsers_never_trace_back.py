"""Property tests (hypothesis) of every parser a user feeds: stroke TOML, flight path
files, capture CSV/BVH, swim path files and the CLI's numbers. Each input gives either a
valid result or a one-line :class:`FlapsimError` (the CLI prints it and exits 2); never
another exception (a traceback). Kept small: tens of examples each, no deadline."""

import argparse
import math
import string

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flapsim.core.errors import FlapsimError

FAST = settings(max_examples=40, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

# JSON/TOML-like values, nested a little
scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8))
values = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
    max_leaves=12)


def one_line(exc: FlapsimError) -> None:
    text = str(exc)
    assert text and "\n" not in text, repr(text)


# -- stroke files ---------------------------------------------------------------------

def _stroke_dicts():
    from flapsim.swim.strokes import dof_names

    dofs = sorted(dof_names())
    joints = sorted({d.split(".")[0] for d in dofs})
    pairs = st.lists(st.tuples(st.floats(-0.5, 1.5), st.floats(-400, 400)), min_size=0,
                     max_size=4).map(lambda ps: [list(p) for p in ps])
    key_lists = st.one_of(pairs, values)
    joint_table = st.dictionaries(st.sampled_from(["flex", "abd", "rot", "bend", "twist", "x"]),
                                  key_lists, max_size=3)
    keys = st.one_of(st.dictionaries(st.sampled_from(joints + ["nope"]), joint_table,
                                     max_size=3), values)
    pose = st.one_of(st.dictionaries(st.sampled_from(dofs[:6] + ["bad.dof"]),
                                     st.one_of(st.floats(-200, 200), values), max_size=3),
                     values)
    return st.fixed_dictionaries({}, optional={
        "name": values, "period_s": st.one_of(st.floats(0, 12), values),
        "posture": st.sampled_from(["prone", "upright", "sideways"]),
        "interpolation": st.sampled_from(["pchip", "linear", "cubic"]),
        "pose": pose, "keys": keys, "mirror": values, "perturb": values, "cycle": values})


@FAST
@given(raw=_stroke_dicts())
def test_stroke_contents_parse_or_fail_in_one_line(raw):
    from flapsim.swim.strokes import Stroke, parse_stroke

    try:
        s = parse_stroke(raw, "s.toml")
    except FlapsimError as exc:
        one_line(exc)
        return
    assert isinstance(s, Stroke) and s.keys  # a stroke that swims something
    assert 0.2 <= s.period_s <= 10.0
    for key in s.keys.values():
        assert np.all((key[0] >= 0) & (key[0] < 1)) and np.all(np.isfinite(key[1]))


@FAST
@given(data=st.one_of(st.binary(max_size=200),
                      st.text(string.printable, max_size=200).map(str.encode),
                      st.sampled_from([b"", b'name = "x"\n', b"\xff\xfe\x00b", b"[pose]\n",
                                       b'[keys.neck]\nbend = [[1.5, 3]]\n',
                                       'name = "\u00e9"'.encode("latin-1")])))
def test_stroke_files_of_any_bytes(tmp_path, data):
    from flapsim.swim.strokes import load_stroke

    f = tmp_path / "s.toml"
    f.write_bytes(data)
    try:
        load_stroke(str(f))
    except FlapsimError as exc:
        one_line(exc)


@pytest.mark.parametrize("data, fragment", [
    (b"", "no keys"),
    (b'name = "only a name"\n', "no keys"),
    (b"\x00\x01\x02binary", "binary"),
    ('name = "caf\u00e9"\n'.encode("latin-1"), "not UTF-8"),
    (b'[keys.neck]\nbend = [[0.0, 1], [1.5, 3]]\n', "phase 1.5"),
    (b"pose = 3\n", "[pose] must be a table"),
    (b'[keys.neck]\nbend = [[0.0, 1e300]]\n', "a key of 1e+300 deg"),
    (b'[pose]\n"neck.bend" = 7000\n', "within +-1080"),
])
def test_bad_stroke_files_name_the_problem(tmp_path, data, fragment):
    from flapsim.swim.strokes import load_stroke

    f = tmp_path / "s.toml"
    f.write_bytes(data)
    with pytest.raises(FlapsimError, match=None) as info:
        load_stroke(str(f))
    one_line(info.value)
    assert fragment in str(info.value)


# -- flight path files (flapsim.bird.tasks.path_control) ----------------------------------------------

# Any float (NaN/inf, 1e300, and junk): FlightPath bounds coordinates and length (a 4.6e8 m
# path once asked numpy for a 69 GB sample array, a 1e300 m one raised scipy's ValueError).
num_text = st.one_of(st.floats().map(repr),
                     st.sampled_from(["nan", "inf", "-inf", "1e999", "4.6e8", "1e300", ""]),
                     st.integers(-100, 100).map(str), st.text("0123456789.-", max_size=4))
coords = st.one_of(st.floats(), st.sampled_from([math.nan, math.inf, -math.inf, 4.6e8, 1e300]))


@FAST
@given(rows=st.lists(st.lists(num_text, min_size=0, max_size=4), max_size=6),
       header=st.sampled_from(["x,y,z", "x,y", "a,b,c", ""]))
def test_flight_path_csv(tmp_path, rows, header):
    from flapsim.bird.tasks.path_control import FlightPath, load_path

    f = tmp_path / "p.csv"
    f.write_text(header + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    try:
        p = load_path(f)
    except FlapsimError as exc:
        one_line(exc)
        return
    assert isinstance(p, FlightPath) and p.length > 0 and np.all(np.isfinite(p.points))


@FAST
@given(data=st.one_of(st.recursive(st.one_of(st.none(), st.booleans(), coords,
                                             st.text(max_size=4)),
                                   lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                           st.dictionaries(st.sampled_from(
                                                               ["points", "x"]), inner,
                                                               max_size=2)), max_leaves=12),
                      st.lists(st.lists(coords, max_size=4), max_size=5)))
def test_flight_path_json(tmp_path, data):
    import json

    from flapsim.bird.tasks.path_control import FlightPath, load_path

    f = tmp_path / "p.json"
    f.write_text(json.dumps(data))
    try:
        p = load_path(f)
    except FlapsimError as exc:
        one_line(exc)
        return
    assert isinstance(p, FlightPath) and np.all(np.isfinite(p.points))


# -- swim path files (flapsim.swim.goals) ---------------------------------------------

@FAST
@given(data=st.one_of(st.binary(max_size=120),
                      st.lists(st.lists(num_text, max_size=3), max_size=6).map(
                          lambda rows: "\n".join(", ".join(r) for r in rows).encode())))
def test_swim_path_files(tmp_path, data):
    from flapsim.swim.goals import load_path

    f = tmp_path / "p.txt"
    f.write_bytes(data)
    try:
        p = load_path(str(f))
    except FlapsimError as exc:
        one_line(exc)
        return
    assert np.all(np.isfinite(p.points)) and len(p.points) >= 2


# -- capture files (flapsim.bird.flight.capture) -----------------------------------------------

def _capture_csv(n_frames: int, columns_cut: int, bad_cell: str | None, dt: float) -> str:
    from flapsim.bird.body.params import DOF_NAMES

    cols = ["time_s"] + [f"{n}_deg" for n in DOF_NAMES]
    cols = cols[: len(cols) - columns_cut]
    t = np.arange(n_frames) * dt
    rows = [",".join(cols)]
    for k in range(n_frames):
        # a flapping shoulder (cycles at 10 Hz) so that wingbeats can be found
        vals = [f"{t[k]:.6f}"] + [f"{40 * math.sin(2 * math.pi * 10 * t[k] + j):.3f}"
                                  for j in range(len(cols) - 1)]
        if bad_cell is not None and k == n_frames // 2:
            vals[min(1, len(vals) - 1)] = bad_cell
        rows.append(",".join(vals))
    return "\n".join(rows) + "\n"


@FAST
@given(n_frames=st.integers(0, 120), cut=st.integers(0, 3),
       bad=st.one_of(st.none(), st.sampled_from(["nan", "abc", "", "1e999", "1,2"])),
       dt=st.sampled_from([1 / 240, 0.0, -0.01]))
def test_capture_csv(tmp_path, n_frames, cut, bad, dt):
    from flapsim.bird.flight.capture import CaptureSet, load_capture

    f = tmp_path / "c.csv"
    f.write_text(_capture_csv(n_frames, cut, bad, dt))
    try:
        c = load_capture(f)
    except FlapsimError as exc:
        one_line(exc)
        return
    assert isinstance(c, CaptureSet)


@FAST
@given(data=st.one_of(st.binary(max_size=200), st.text(max_size=200).map(str.encode),
                      st.sampled_from([b"HIERARCHY\nROOT x\n{\n", b"HIERARCHY\nMOTION\nFrames: 2\n",
                                       b"HIERARCHY\nROOT trunk\n{\nOFFSET 0 0 0\nCHANNELS 3 "
                                       b"Zrotation Xrotation Yrotation\n}\nMOTION\nFrames: 2\n"
                                       b"Frame Time: 0.004\n1 2 3\n4 5 6\n"])))
def test_capture_bvh(tmp_path, data):
    from flapsim.bird.flight.capture import load_capture

    f = tmp_path / "c.bvh"
    f.write_bytes(data)
    try:
        load_capture(f)
    except FlapsimError as exc:
        one_line(exc)


# -- the command line's numbers ---------------------------------------------------------

@FAST
@given(text=st.one_of(st.text(max_size=12), st.floats(allow_nan=True).map(repr),
                      st.integers().map(str)),
       option=st.sampled_from([("swim", "--density"), ("swim", "--fps"), ("swim", "--current"),
                               ("swim", "--target"), ("swim", "--source"), ("demo", "--mass"),
                               ("bench", "--polygons"), ("animate", "--seconds"),
                               ("sweep", "--workers"), ("modes", "--count")]))
def test_cli_numbers_parse_or_exit_2_in_one_line(text, option, capsys):
    from flapsim.cli import main as cli

    command, flag = option
    argv = [command] + (["m.xml"] if command == "modes" else []) \
        + (["forces"] if command == "bench" else []) \
        + (["--vary", "rate", "--values", "1"] if command == "sweep" else []) + [f"{flag}={text}"]
    parser = cli.build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
        assert exc.code == 2 and len(err) == 1 and flag in err[0], err
        return
    value = getattr(args, flag.lstrip("-").replace("-", "_"))
    for v in np.atleast_1d(np.asarray(value, dtype=float)):
        assert math.isfinite(v)


def test_the_range_types_agree_with_their_ranges():
    from flapsim.core.validate import RANGES, quantity

    for name, r in RANGES.items():
        parse = quantity(name)
        assert parse(repr(float(r.hi))) == r.hi
        with pytest.raises(argparse.ArgumentTypeError, match="must be"):
            parse(repr(float(r.hi) * 1.001 + 1))
        if r.lo_open:
            with pytest.raises(argparse.ArgumentTypeError):
                parse(repr(float(r.lo)))
        else:
            assert parse(repr(float(r.lo))) == r.lo
