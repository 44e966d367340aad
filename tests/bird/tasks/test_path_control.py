"""Path control: path files, the spline, Hermite recovery, the bank of eq. 5, the paper's
measures, and the task's options on the command line."""

import json

import mujoco
import numpy as np
import pytest

from flapsim.bird.tasks.path_control import (
    FlightPath,
    bank_for_turn,
    hermite,
    load_path,
    quat_distance,
)
from flapsim.cli.main import main
from flapsim.core.errors import DataFileError, InputError


def _arc(R=20.0, turn=4.7, n=40):
    a = np.linspace(0, turn, n)
    return np.stack([R * np.sin(a), R * (1 - np.cos(a)), 10 + 0 * a], axis=1)


def test_path_files_load_and_bad_ones_get_one_line_errors(tmp_path):
    pts = _arc(n=5)
    csv = tmp_path / "p.csv"
    np.savetxt(csv, pts, delimiter=",", header="x,y,z", comments="")
    js = tmp_path / "p.json"
    js.write_text(json.dumps(pts.tolist()))
    jd = tmp_path / "d.json"
    jd.write_text(json.dumps({"points": pts.tolist()}))
    for f in (csv, js, jd):
        np.testing.assert_allclose(load_path(f).points, pts, atol=1e-12)
    bad = {
        "binary.csv": b"\x89PNG\r\n\x1a\n\x00\x00",
        "noheader.csv": b"1,2,3\n4,5,6\n",
        "nan.csv": b"x,y,z\n0,0,0\nnan,1,1\n",
        "one.csv": b"x,y,z\n0,0,0\n",
        "dup.csv": b"x,y,z\n0,0,0\n0,0,0\n1,1,1\n",
        "words.json": b'["a", "b"]',
    }
    for name, content in bad.items():
        f = tmp_path / name
        f.write_bytes(content)
        with pytest.raises(DataFileError) as e:
            load_path(f)
        assert "\n" not in str(e.value) and name in str(e.value)
    with pytest.raises(DataFileError, match="does not exist"):
        load_path(tmp_path / "missing.csv")


def test_a_bad_point_is_named_by_its_line_or_index(tmp_path):
    # the message says where the file is wrong: the CSV's line (blank lines counted, as an
    # editor counts them) or the JSON list's point, 1-based
    cases = {
        "short.csv": (b"x,y,z\n0,0,0\n\n1,2\n", "line 4 must be 3 numbers x, y, z, got 2 values"),
        "word.csv": (b"x,y,z\n0,0,0\n1,abc,0\n", "line 3: 'abc' is not a number"),
        "short.json": (b"[[0,0,0],[1,2]]", "point 2 must be 3 numbers x, y, z, got 2 values"),
        "word.json": (b'[[0,0,0],[1,2,"q"]]', "point 2: 'q' is not a number"),
        "flag.json": (b"[[0,0,0],[1,true,2]]", "point 2: 'True' is not a number"),
        "object.json": (b'{"a": 1}', "expected a JSON list"),
    }
    for name, (content, message) in cases.items():
        f = tmp_path / name
        f.write_bytes(content)
        with pytest.raises(DataFileError) as e:
            load_path(f)
        assert message in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_spline_passes_through_the_points_and_measures_length():
    # two points: a straight segment; its length and closest points are elementary
    p = FlightPath(np.array([[0.0, 0, 10], [30.0, 40, 10]]))
    assert p.length == pytest.approx(50.0, rel=1e-9)
    assert p.closest(np.array([15.0, 20.0, 13.0])) == pytest.approx(25.0, abs=0.05)  # grid 5 cm
    np.testing.assert_allclose(p.tangent(10.0), [0.6, 0.8, 0.0], atol=1e-9)
    # a circle's arc: the spline interpolates its points, and its length approaches R * angle
    pts = _arc(R=20.0, turn=np.pi, n=60)
    c = FlightPath(pts)
    np.testing.assert_allclose(c.point(0.0), pts[0], atol=1e-12)
    np.testing.assert_allclose(c.point(c.length), pts[-1], atol=1e-9)
    # 60 knots over a half circle: the chordal spline is within 1e-4 of the true length
    assert c.length == pytest.approx(20.0 * np.pi, rel=1e-4)


def test_hermite_curve_meets_its_ends():
    p0, v0 = np.array([0.0, 0, 0]), np.array([7.0, 0, 0])
    p1, v1 = np.array([7.0, 2, 1]), np.array([0.0, 7, 0])
    T = 1.0
    for t, p, v in ((0.0, p0, v0), (T, p1, v1)):
        pt, vt, _ = hermite(p0, v0, p1, v1, T, t)
        np.testing.assert_allclose(pt, p, atol=1e-12)
        np.testing.assert_allclose(vt, v, atol=1e-12)
    # a straight constant-velocity segment has no acceleration anywhere
    _, _, a = hermite(p0, v0, p0 + v0 * T, v0, T, 0.37)
    np.testing.assert_allclose(a, 0.0, atol=1e-12)


def test_bank_balances_the_centrifugal_force():
    # level turn of radius r at speed v: centripetal acceleration v^2 / r to the left, so
    # tan(bank) = v^2 / (g r) (eq. 5)
    v, r = 7.0, 20.0
    bank = bank_for_turn(np.array([v, 0, 0]), np.array([0.0, v * v / r, 0]))
    assert bank == pytest.approx(np.arctan(v * v / (9.81 * r)), abs=1e-12)
    assert bank_for_turn(np.array([v, 0, 0]), np.array([0.0, -v * v / r, 0])) == pytest.approx(-bank)


def test_quaternion_distance_is_the_log_norm_half_the_rotation_angle():
    # the paper's ||log(q_a^-1 q_b)|| (Lee 2008: exp(v) = (cos|v|, sin|v| v/|v|)) is half the
    # angle of the rotation between the two orientations
    q = np.array([1.0, 0, 0, 0])
    r = np.empty(4)
    mujoco.mju_axisAngle2Quat(r, np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), 0.7)
    assert quat_distance(q, r) == pytest.approx(0.35, abs=1e-9)
    assert quat_distance(r, -r) == pytest.approx(0.0, abs=1e-7)  # q and -q: the same rotation


def test_path_cli_errors(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,z\n0,0,0\n")
    assert main(["fly", "--controller", "learned", "--path", str(bad)]) == 2
    assert "bad.csv" in capsys.readouterr().err
    good = tmp_path / "good.csv"
    np.savetxt(good, _arc(n=5), delimiter=",", header="x,y,z", comments="")
    assert main(["fly", "--path", str(good)]) == 2  # the base controller cannot steer
    assert "--controller learned" in capsys.readouterr().err


def test_fly_path_without_wingbeats_gets_the_tasks_time_budget(tmp_path, monkeypatch):
    """``fly --path`` without ``--wingbeats`` hands the task no wingbeat count, so it is
    flown for eval's time budget in seconds (the old count of 0.1075 s reference wingbeats
    gave shorter learned wingbeats less time); ``--wingbeats N`` still caps it at N."""
    import flapsim.cli.commands.fly as fly_command

    seen = []

    class Stop(Exception):
        pass

    def capture(task, *a, **kw):
        seen.append(task.max_wingbeats)
        raise Stop

    monkeypatch.setattr(fly_command, "fly_task", capture)
    f = tmp_path / "arc.csv"
    np.savetxt(f, _arc(n=5), delimiter=",", header="x,y,z", comments="")
    for extra in ([], ["--wingbeats", "7"]):
        with pytest.raises(Stop):
            main(["fly", "--controller", "learned", "--path", str(f), *extra])
    assert seen == [None, 7]


def test_recovery_curve_on_the_path_is_the_path_itself():
    # a bird on a straight path flying along it at the asked speed: the Hermite curve from its
    # position and velocity to the look-ahead point and tangent is the straight line, so the
    # position asked at the end of a wingbeat of dt is p + v dt and the heading is the path's
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    h = np.radians(30.0)
    u = np.array([np.cos(h), np.sin(h), 0.0])
    path = FlightPath(np.array([[0, 0, 10.0], *(np.array([0, 0, 10.0]) + 50 * u[None])]))
    trim = Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0]))  # level, 2.9 deg angle of attack
    tgt = PathTarget(trim, path, speed=7.0, ki_speed=0.0, ki_altitude=0.0)
    p = np.array([0, 0, 10.0]) + 5.0 * u
    v = 7.0 * u
    tgt.begin(p, v)
    dt = 0.1075
    e0 = CycleEnd(None, np.zeros(8), p + v * dt, np.array([1.0, 0, 0, 0]), v, dt, 0.0)
    tgt(e0)
    pd, qd = tgt.desired[-1]
    # tolerance: the closest point is found on 5 cm samples, so the look-ahead point may sit
    # up to 2.5 cm along the line; its Hermite weight at t = dt (3u^2 - 2u^3, u = dt / 1 s) is
    # 0.032, i.e. < 1 mm, and it stays on the line (no sideways error at all)
    np.testing.assert_allclose(pd, p + v * dt, atol=1e-3)
    assert abs(np.cross(pd - p, u)[2]) < 1e-9
    # asked attitude: heading 30 deg, pitched by the trim's angle of attack, no bank: it is
    # the heading rotation followed by the pitch, ||log|| = half the angle of attack
    assert quat_distance(qd, np.array([np.cos(h / 2), 0, 0, np.sin(h / 2)])) == pytest.approx(
        0.5 * abs(trim.aoa), abs=1e-9)


def test_the_desired_position_is_the_curve_at_the_wingbeats_actual_end():
    # the target is asked at P0's predicted end (0.1075 s) but the wingbeat flown lasts 0.1 s
    # (its own timewarp): on a straight path flown at 7 m/s the curve is the line, so the
    # desired position must be p + v 0.1, not p + v 0.1075 (5 cm further); tolerance as in
    # the test above (5 cm closest-point samples weighted < 0.032 by the Hermite basis)
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    path = FlightPath(np.array([[0, 0, 10.0], [100.0, 0, 10.0]]))
    trim = Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0]))
    tgt = PathTarget(trim, path, speed=7.0, ki_speed=0.0, ki_altitude=0.0)
    p, v = np.array([5.0, 0, 10.0]), np.array([7.0, 0, 0])
    tgt.begin(p, v)
    tgt(CycleEnd(None, np.zeros(8), p + v * 0.1075, np.array([1.0, 0, 0, 0]), v, 0.1075, 0.0))
    np.testing.assert_allclose(tgt.desired[-1][0], p + v * 0.1075, atol=1e-3)
    q_asked = tgt.desired[-1][1].copy()
    tgt.end(0.1)
    np.testing.assert_allclose(tgt.desired[-1][0], p + v * 0.1, atol=1e-3)
    np.testing.assert_array_equal(tgt.desired[-1][1], q_asked)  # the attitude asked stays
    with pytest.raises(InputError, match="after the target"):
        tgt.end(0.1)  # once per wingbeat


def test_near_the_paths_end_the_look_ahead_continues_straight_on():
    # 2 m before the end of a 20 m straight path, flying along it at 7 m/s: the look-ahead
    # point (7 m on) lies beyond the end, on the line's continuation, so the recovery curve is
    # still the line and the desired position after 0.1 s is p + 0.7 m (clamped to the end
    # point, the curve would have to cover 2 m in the second it is given: 0.36 m in 0.1 s)
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    path = FlightPath(np.array([[0, 0, 10.0], [20.0, 0, 10.0]]))
    p, t = path.ahead(25.0)
    np.testing.assert_allclose(p, [25.0, 0, 10.0], atol=1e-9)
    np.testing.assert_allclose(t, [1.0, 0, 0], atol=1e-9)
    tgt = PathTarget(Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0])), path, speed=7.0,
                     ki_speed=0.0, ki_altitude=0.0)
    p, v = np.array([18.0, 0, 10.0]), np.array([7.0, 0, 0])
    tgt.begin(p, v)
    tgt(CycleEnd(None, np.zeros(8), p + v * 0.1, np.array([1.0, 0, 0, 0]), v, 0.1, 0.0))
    # tolerance: the 5 cm closest-point samples, weighted < 0.03 by the Hermite basis at 0.1 s
    np.testing.assert_allclose(tgt.desired[-1][0], p + v * 0.1, atol=2e-3)


def test_in_a_crosswind_the_bird_crabs_so_that_its_ground_track_is_the_path():
    # a 2 m/s wind from the right (+y) across a path along +x, airspeed 7 m/s: the air
    # velocity that makes good +x is (sqrt(49 - 4), -2, 0), a heading of -asin(2/7) = -16.6 deg
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget, _attitude_quat

    path = FlightPath(np.array([[0, 0, 10.0], [100.0, 0, 10.0]]))
    trim = Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0]))
    w = np.array([0.0, 2.0, 0.0])
    tgt = PathTarget(trim, path, speed=7.0, ki_speed=0.0, ki_altitude=0.0, wind=lambda p, t: w)
    ground = np.array([np.sqrt(45.0), 0.0, 0.0])
    p = np.array([5.0, 0.0, 10.0])
    tgt.begin(p, ground)
    snap = type("S", (), {"physics": np.zeros(1)})()
    S = tgt(CycleEnd(snap, np.zeros(8), p + 0.1 * ground, np.array([1.0, 0, 0, 0]), ground, 0.1, 0.0))
    heading = -np.arcsin(2.0 / 7.0)
    assert quat_distance(tgt.desired[-1][1], _attitude_quat(heading, trim.aoa, 0.0)) < 1e-3
    # S carries the ground velocity in the body frame: its speed is the ground speed
    assert np.linalg.norm(S[2:5]) == pytest.approx(np.sqrt(45.0), abs=0.02)


@pytest.mark.parametrize("k", [0.0, 0.1])
def test_short_of_airspeed_the_climb_asked_gives_way(k):
    """Speed first: on a 7 deg climb, a bird on the path along its tangent at 5 m/s while
    7 m/s is asked (speed integral off) is asked the climb whose vertical speed is the path's,
    7 sin 7 deg, less k x (7 - 5) x 7: for k = 0.1 asin((0.853 - 1.4) / 7) = -4.5 deg, a
    gentle descent to win back speed; k = 0 (and any bird at the speed asked) gets 7 deg."""
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    a = np.radians(7.0)
    u = np.array([np.cos(a), 0.0, np.sin(a)])
    path = FlightPath(np.array([[0, 0, 10.0], *(np.array([0, 0, 10.0]) + 100 * u[None])]))
    trim = Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0]))
    snap = type("S", (), {"physics": np.zeros(1)})()
    for speed_now, want in ((5.0, np.arcsin((7.0 * np.sin(a) - k * 2.0 * 7.0) / 7.0)), (7.0, a)):
        tgt = PathTarget(trim, path, speed=7.0, ki_speed=0.0, ki_altitude=0.0,
                         climb_per_speed_deficit=k)
        p, v = np.array([0, 0, 10.0]) + 5.0 * u, speed_now * u
        tgt.begin(p, v)
        tgt(CycleEnd(snap, np.zeros(8), p + 0.1 * v, np.array([1.0, 0, 0, 0]), v, 0.1, 0.0))
        expected = a if k == 0.0 else want
        # tolerance: the closest point's 5 cm samples, weighted < 0.03 by the Hermite basis
        assert tgt.asked[-1][2] == pytest.approx(expected, abs=2e-3)
    with pytest.raises(InputError, match="missing airspeed"):
        PathTarget(trim, path, climb_per_speed_deficit=-0.1)


@pytest.mark.parametrize("memory", [0.0, 1.0])
def test_the_bird_crabs_into_the_winds_lagged_average_and_is_carried_by_the_rest(memory):
    """Still air for the first wingbeat, then a 3 m/s wind from the right across a path along
    +x. The crab (heading -asin(w / 7)) uses the wind averaged with time constant ``memory``:
    after one 0.1 s wingbeat 3 (1 - exp(-0.1 / memory)) = 0.285 m/s for 1 s, all 3 m/s for 0;
    the ground velocity asked is that air velocity plus the wind of the moment."""
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget, _attitude_quat

    path = FlightPath(np.array([[0, 0, 10.0], [100.0, 0, 10.0]]))
    trim = Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0]))
    tgt = PathTarget(trim, path, speed=7.0, ki_speed=0.0, ki_altitude=0.0, wind_memory_s=memory,
                     wind=lambda p, t: np.array([0.0, 3.0 if t > 0.05 else 0.0, 0.0]))
    v = np.array([7.0, 0.0, 0.0])
    for i, p in enumerate((np.array([5.0, 0.0, 10.0]), np.array([5.7, 0.0, 10.0]))):
        tgt.begin(p, v)
        snap = type("S", (), {"physics": np.array([0.1 * i])})()
        S = tgt(CycleEnd(snap, np.zeros(8), p + 0.1 * v, np.array([1.0, 0, 0, 0]), v, 0.1, 0.0))
    w_crab = 3.0 * (1.0 - np.exp(-0.1 / memory)) if memory > 0 else 3.0
    heading = -np.arcsin(w_crab / 7.0)
    assert tgt.asked[-1][1] == pytest.approx(heading, abs=1e-3)
    assert quat_distance(tgt.desired[-1][1], _attitude_quat(heading, trim.aoa, 0.0)) < 1e-3
    # the ground speed asked: the air velocity (7 m/s along the heading) plus the 3 m/s wind
    air = 7.0 * np.array([np.cos(heading), np.sin(heading), 0.0])
    assert np.linalg.norm(S[2:5]) == pytest.approx(np.linalg.norm(air + [0.0, 3.0, 0.0]), abs=0.02)
    with pytest.raises(InputError, match="wind memory"):
        PathTarget(trim, path, wind_memory_s=-1.0)


@pytest.mark.parametrize("lead", [0.0, 0.2])
def test_the_bank_asked_is_the_recovery_curves_bank_lead_seconds_on(lead):
    # a bird 1 m left of a straight path along +x, flying along it at 7 m/s: the recovery
    # curve to the point 7 m ahead (tangent 7 m/s, T = 1 s) is x = x0 + 7 t and
    # y(u) = (2u^3 - 3u^2 + 1) y0, so at time u its acceleration is (0, (12u - 6) y0, 0) and
    # its velocity (7, (6u^2 - 6u) y0, 0); eq. 5's bank is atan(a_lat / g) with a_lat the
    # acceleration across the velocity. Asked at u = dt + lead; the curve itself (the
    # evaluation's desired attitude) at u = dt. Tolerance: the closest path point is found on
    # 5 cm samples, which moves the look-ahead point along x by < 2.5 cm: < 1e-4 rad here
    from flapsim.bird.control.targets import GRAVITY, Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    def bank(u, y0=1.0):
        ay, vy = (12 * u - 6) * y0, (6 * u * u - 6 * u) * y0
        return np.arctan(ay * 7.0 / np.hypot(7.0, vy) / GRAVITY)

    path = FlightPath(np.array([[0, 0, 10.0], [200.0, 0, 10.0]]))
    tgt = PathTarget(Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0])), path, speed=7.0,
                     ki_speed=0.0, ki_altitude=0.0, bank_lead_s=lead)
    p, v, dt = np.array([5.0, 1.0, 10.0]), np.array([7.0, 0, 0]), 0.1
    tgt.begin(p, v)
    tgt(CycleEnd(None, np.zeros(8), p + v * dt, np.array([1.0, 0, 0, 0]), v, dt, 0.0))
    assert tgt.asked[-1][3] == pytest.approx(bank(dt + lead), abs=1e-4)
    assert bank(0.1) == pytest.approx(np.radians(-26.0), abs=np.radians(0.5))  # toward the path
    # the heading asked is the curve's direction at the wingbeat's end, and the desired
    # attitude (Eo) keeps the curve's own bank there: heading, then the pitch by the angle of
    # attack, then the bank about x
    _, heading, climb, _ = tgt.asked[-1]
    h = np.arctan2((6 * dt * dt - 6 * dt) * 1.0, 7.0)
    assert heading == pytest.approx(h, abs=1e-4) and abs(climb) < 1e-9
    qh = np.array([np.cos(h / 2), 0, 0, np.sin(h / 2)])
    qp = np.array([np.cos(-tgt.trim.aoa / 2), 0, np.sin(-tgt.trim.aoa / 2), 0])
    qb = np.array([np.cos(-bank(dt) / 2), np.sin(-bank(dt) / 2), 0, 0])
    q, t = np.empty(4), np.empty(4)
    mujoco.mju_mulQuat(t, qh, qp)
    mujoco.mju_mulQuat(q, t, qb)
    assert quat_distance(tgt.desired[-1][1], q) < 1e-4


@pytest.mark.parametrize("cap", [45.0, 50.0, 60.0])
def test_the_bank_asked_stops_at_the_largest_bank(cap, capsys, tmp_path):
    # the bird 3 m left of a straight path: the recovery curve's bank at the wingbeat's end
    # (lead 0, dt = 0.1 s, u = 0.1) is atan(a_lat / g) with a = (12u - 6) 3 = -14.4 m/s^2 across
    # and v = (7, (6u^2 - 6u) 3) = (7, -1.62): a_lat = 14.4 * 7 / 7.185 = 14.03 m/s^2, a bank
    # of 55.0 deg toward the path; asked, it is cut at the cap (tolerance: as above)
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    path = FlightPath(np.array([[0, 0, 10.0], [200.0, 0, 10.0]]))
    tgt = PathTarget(Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0])), path, speed=7.0,
                     ki_speed=0.0, ki_altitude=0.0, bank_lead_s=0.0, max_bank_deg=cap)
    p, v, dt = np.array([5.0, 3.0, 10.0]), np.array([7.0, 0, 0]), 0.1
    tgt.begin(p, v)
    tgt(CycleEnd(None, np.zeros(8), p + v * dt, np.array([1.0, 0, 0, 0]), v, dt, 0.0))
    curve = -np.degrees(np.arctan(14.4 * 7.0 / np.hypot(7.0, 1.62) / 9.81))
    assert curve == pytest.approx(-55.0, abs=0.1)
    assert np.degrees(tgt.asked[-1][3]) == pytest.approx(max(curve, -cap), abs=0.01)
    for bad in (5.0, 85.0, float("nan")):
        with pytest.raises(InputError, match="largest bank"):
            PathTarget(Trim(np.zeros(8)), path, max_bank_deg=bad)
    assert main(["eval", "--scenario", "sinusoid-sharp", "--config",
                 _config(tmp_path, "[path]\nmax_bank_deg = 90")]) == 2
    err = capsys.readouterr().err.strip()
    assert "max_bank_deg must be 10..80 deg" in err and "\n" not in err


@pytest.mark.parametrize("cap", [15.0, 25.0, 35.0])
def test_the_climb_asked_stops_at_the_steepest_climb(cap, capsys, tmp_path):
    # the bird on a straight path climbing 30 deg, flying along it at 7 m/s: the recovery
    # curve runs along the path, so the climb asked is the path's 30 deg, cut at the cap
    # (tolerance: the Hermite curve of a bird on its line is the line, to rounding)
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    g = np.radians(30.0)
    u = np.array([np.cos(g), 0.0, np.sin(g)])
    path = FlightPath(np.array([[0, 0, 10.0], [0, 0, 10.0] + 200.0 * u]))
    tgt = PathTarget(Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0])), path, speed=7.0,
                     ki_speed=0.0, ki_altitude=0.0, bank_lead_s=0.0, max_climb_deg=cap)
    p, v, dt = np.array([0, 0, 10.0]) + 20.0 * u, 7.0 * u, 0.1
    tgt.begin(p, v)
    tgt(CycleEnd(None, np.zeros(8), p + v * dt, np.array([1.0, 0, 0, 0]), v, dt, 0.0))
    assert np.degrees(tgt.asked[-1][2]) == pytest.approx(min(30.0, cap), abs=1e-6)
    for bad in (2.0, 70.0, float("nan")):
        with pytest.raises(InputError, match="steepest climb"):
            PathTarget(Trim(np.zeros(8)), path, max_climb_deg=bad)
    assert main(["eval", "--scenario", "climb-turn-30", "--config",
                 _config(tmp_path, "[path]\nmax_climb_deg = 75")]) == 2
    err = capsys.readouterr().err.strip()
    assert "max_climb_deg must be 5..60 deg" in err and "\n" not in err


def _config(tmp_path, text: str) -> str:
    """A control configuration file holding ``text``."""
    f = tmp_path / "control.toml"
    f.write_text(text + "\n")
    return str(f)


def test_a_bank_lead_outside_the_look_ahead_is_a_one_line_error(capsys, tmp_path):
    from flapsim.bird.control.targets import Trim
    from flapsim.bird.tasks.path_control import PathTarget

    path = FlightPath(np.array([[0, 0, 10.0], [20.0, 0, 10.0]]))
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(InputError, match="bank lead"):
            PathTarget(Trim(np.zeros(8)), path, bank_lead_s=bad)
    assert main(["eval", "--scenario", "figure8-level", "--config",
                 _config(tmp_path, "[path]\nbank_lead_s = 2")]) != 0
    assert "bank_lead_s must be 0..1 s" in capsys.readouterr().err
    for bad in (-1.0, 100.0, float("nan")):
        with pytest.raises(InputError, match="angle of attack per g"):
            PathTarget(Trim(np.zeros(8)), path, aoa_per_g_deg=bad)
    assert main(["eval", "--scenario", "figure8-level", "--config",
                 _config(tmp_path, "[path]\naoa_per_g_deg = -5")]) != 0
    err = capsys.readouterr().err.strip()
    assert "aoa_per_g_deg must be 0..90 deg" in err and "\n" not in err
    assert main(["eval", "--scenario", "figure8-level", "--speed", "1"]) != 0
    err = capsys.readouterr().err.strip()
    assert "--speed must be 3..12 m/s" in err and "\n" not in err


def test_ahead_of_a_tight_turn_the_speed_asked_is_where_it_needs_the_load_factor_given():
    """``turn_load_factor`` n: ahead of a level turn of radius r the speed asked is the one at
    which that turn needs exactly n, i.e. sqrt(1 + (v^2 / (g r))^2) = n (4 m and 1.25 g:
    5.42 m/s); the floor and the speed asked bound it, a straight far from the turn keeps the
    speed asked, and 0 turns the slowing off. Tolerance 1 %: away from its ends the spline
    through 48 points a turn has the circle's curvature within 0.3 %."""
    from flapsim.bird.control.targets import GRAVITY, Trim
    from flapsim.bird.flight.cycle import CycleEnd
    from flapsim.bird.tasks.path_control import PathTarget

    a = np.linspace(0.0, 2.5 * np.pi, 61)
    lead_in = np.stack([np.linspace(-40.0, 0.0, 9)[:-1], np.zeros(8), np.full(8, 10.0)], 1)
    circle = np.stack([4.0 * np.sin(a), 4.0 * (1 - np.cos(a)), np.full_like(a, 10.0)], 1)
    path = FlightPath(np.concatenate([lead_in, circle]))
    trim = Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0]))
    tgt = PathTarget(trim, path, speed=7.0, turn_load_factor=1.25, turn_speed_floor=3.0)
    v = tgt.speed_for(50.0, 10.0)  # 10..20 m into the circle
    n = np.sqrt(1.0 + (v**2 / (GRAVITY * 4.0)) ** 2)
    assert n == pytest.approx(1.25, rel=0.01)
    assert v == pytest.approx(np.sqrt(GRAVITY * 4.0 * 0.75), rel=0.01)
    assert tgt.speed_for(0.0, 14.0) == 7.0  # 26 m before the turn
    assert tgt.speed_for(0.0, 45.0) <= v + 1e-9  # the turn is within the window
    assert PathTarget(trim, path, speed=7.0, turn_load_factor=1.25).speed_for(50.0, 10.0) == 6.5
    assert PathTarget(trim, path, speed=7.0).speed_for(50.0, 10.0) == 7.0
    # a wide turn needs less than n at the speed asked: no slowing
    assert PathTarget(trim, path, speed=7.0, turn_load_factor=3.0).speed_for(50.0, 10.0) == 7.0
    # the wingbeat's request carries it (no speed integral yet: ki_speed 0)
    tgt = PathTarget(trim, path, speed=7.0, turn_load_factor=1.25, turn_speed_floor=3.0,
                     ki_speed=0.0, ki_altitude=0.0)
    p = path.point(50.0)
    vel = 5.4 * path.tangent(50.0)
    tgt.s = 49.0  # progress so far (it looks for the closest point a few seconds on only)
    tgt.begin(p, vel)
    tgt(CycleEnd(None, np.zeros(8), p + vel * 0.1, np.array([1.0, 0, 0, 0]), vel, 0.1, 0.0))
    assert tgt.asked[-1][0] == pytest.approx(tgt.speed_for(50.0, 2.0 * 7.0), rel=1e-3)
    for bad in (1.0, 0.5, 6.0, float("nan")):
        with pytest.raises(InputError, match="load factor"):
            PathTarget(trim, path, turn_load_factor=bad)
    for bad in (0.1, 8.0, float("nan")):
        with pytest.raises(InputError, match="lowest speed"):
            PathTarget(trim, path, turn_load_factor=1.25, turn_speed_floor=bad)


def test_the_time_allowed_follows_the_speeds_asked():
    """The tasks allow 1.5x the path's flight time at the speeds asked: ``length / speed``
    without slowing, and with it the lead-in at 7 m/s plus the turn at the closed-form
    sqrt(g r sqrt(n^2 - 1)) (5.42 m/s for 4 m at 1.25 g). Tolerance 3 %: the speed asked
    starts to drop two look-ahead distances (14 m) before the turn, and the spline's ends
    bend tighter than its points."""
    from flapsim.bird.control.targets import GRAVITY, Trim
    from flapsim.bird.tasks.path_control import PathTarget

    a = np.linspace(0.0, 2.5 * np.pi, 61)
    lead_in = np.stack([np.linspace(-40.0, 0.0, 9)[:-1], np.zeros(8), np.full(8, 10.0)], 1)
    circle = np.stack([4.0 * np.sin(a), 4.0 * (1 - np.cos(a)), np.full_like(a, 10.0)], 1)
    path = FlightPath(np.concatenate([lead_in, circle]))
    trim = Trim(np.array([0.05, 0, 7.0, 0, -0.35, 0, 0, 0]))
    assert PathTarget(trim, path, speed=7.0).flight_time() == path.length / 7.0
    v_turn = np.sqrt(GRAVITY * 4.0 * 0.75)
    turn_m = 2.5 * np.pi * 4.0
    expect = (40.0 - 14.0) / 7.0 + (14.0 + turn_m) / v_turn  # slowed from 14 m before the turn
    got = PathTarget(trim, path, speed=7.0, turn_load_factor=1.25, turn_speed_floor=3.0).flight_time()
    assert got == pytest.approx(expect, rel=0.03)
    assert got > 1.1 * path.length / 7.0  # 1.18x: not within the tolerance of no slowing
    # a wing that holds only 1.23 g flies the 4 m turn no faster than sqrt(g r sqrt(n^2 - 1))
    # (4.74 m/s), whatever is asked; the lead-in at the speed asked
    v_wing = np.sqrt(GRAVITY * 4.0 * np.sqrt(1.23**2 - 1.0))
    wing = PathTarget(trim, path, speed=7.0).flight_time(wing_load_factor=1.23)
    assert wing == pytest.approx(40.0 / 7.0 + turn_m / v_wing, rel=0.03)
    with pytest.raises(InputError, match="load factor"):
        PathTarget(trim, path).flight_time(wing_load_factor=1.0)


def test_turn_g_options_get_one_line_errors(capsys, tmp_path):
    for text, msg in (("turn_load_factor = 0.9", "turn_load_factor must be 0"),
                      ("climb_per_speed_deficit = 2", "climb_per_speed_deficit must be 0..1"),
                      ("turn_load_factor = 1.3\nturn_speed_floor = 2", "turn_speed_floor must be")):
        config = _config(tmp_path, "[path]\n" + text)
        assert main(["eval", "--scenario", "figure8-level", "--config", config]) != 0
        err = capsys.readouterr().err.strip()
        assert msg in err and "\n" not in err


def test_curvature_and_climb_of_a_helix_are_its_closed_form():
    # a helix of radius R rising c per radian: curvature R / (R^2 + c^2), climb atan(c / R).
    # 48 points a turn: away from the ends the interpolating spline is within 0.5 % of it
    # (its error falls as h^2); the natural ends (zero second derivative) bend it off
    from flapsim.bird.tasks.path_control import FlightPath

    R, c = 4.0, 0.5
    t = np.linspace(0.0, 4 * np.pi, 97)
    path = FlightPath(np.stack([R * np.cos(t), R * np.sin(t), c * t], 1))
    s = np.linspace(0.25, 0.75, 200) * path.length
    np.testing.assert_allclose(path.curvature(s), R / (R * R + c * c), rtol=5e-3)
    g = path.geometry()
    assert g.max_climb_deg == pytest.approx(np.degrees(np.arctan(c / R)), abs=0.2)
    assert g.max_descent_deg == 0.0
    assert g.length_m == pytest.approx(2 * 2 * np.pi * np.hypot(R, c), rel=2e-3)


def test_the_tightest_radius_is_the_brute_force_one_ends_included():
    # independent: the circle through three consecutive points 1 cm apart along the curve,
    # smallest over the whole path (within 1 %: the 1 cm chord against radii of metres).
    # The paper's 3.6 m circle as a natural spline bends tighter near its ends (2.8-2.9 m
    # within its first metre): what the report must show, since the bird is asked to fly it
    from flapsim.bird.tasks import path_shapes as paths
    path = paths.inclined_circle(3.6, 0.0)
    s = np.arange(0.0, path.length, 0.01)
    a, b, c = path.point(s[:-2]), path.point(s[1:-1]), path.point(s[2:])
    ab, bc, ca = (np.linalg.norm(x, axis=1) for x in (b - a, c - b, a - c))
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    with np.errstate(divide="ignore"):
        radius = ab * bc * ca / (2 * area2)
    g = path.geometry()
    assert g.min_radius_m == pytest.approx(radius.min(), rel=1e-2)
    assert s[1:-1][np.argmin(radius)] == pytest.approx(g.min_radius_at_m, abs=0.1)
    assert g.min_radius_m < 3.0  # the end effect, seen
    mid = (s[1:-1] > 3.0) & (s[1:-1] < path.length - 3.0)
    np.testing.assert_allclose(radius[mid], 3.6, rtol=5e-3)  # the circle between
    # held over 2 m of arc (the brute-force curvature 1 / radius, averaged the same way, 1 cm
    # samples): the end spike averages out to within 5 % of the circle, the report's "held"
    k = 1.0 / radius
    held = np.convolve(k, np.full(200, 1.0 / 200), mode="valid").max()
    assert g.sustained_radius_m == pytest.approx(1.0 / held, rel=1e-2)
    assert g.min_radius_m < g.sustained_radius_m < 3.6 * 1.005
    assert g.sustained_radius_m > 3.6 * 0.95


def test_geometry_of_a_straight_climb_and_the_inclined_circles():
    from flapsim.bird.tasks import path_shapes as paths
    from flapsim.bird.tasks.path_control import FlightPath

    a = np.radians(12.0)
    s = np.linspace(0.0, 30.0, 4)
    g = FlightPath(np.stack([s * np.cos(a), np.zeros_like(s), s * np.sin(a)], 1)).geometry()
    assert g.max_climb_deg == pytest.approx(12.0, abs=1e-9)
    assert g.min_radius_m > 1e6 and g.max_descent_deg == 0.0  # straight: curvature ~0
    # the paper's climbing circle of 3.6 m tilted 30 deg climbs and descends 30 deg at most
    g = paths.inclined_circle(3.6, 30.0).geometry()
    assert g.max_climb_deg == pytest.approx(30.0, abs=0.3)
    assert g.max_descent_deg == pytest.approx(30.0, abs=0.3)
    # reversed, a climb becomes a descent
    rev = FlightPath(paths.inclined_circle(3.6, 30.0).points[::-1])
    assert rev.geometry().max_climb_deg == pytest.approx(g.max_descent_deg, abs=1e-6)


def test_a_task_allows_its_path_at_3_m_s_whatever_the_wingbeats_length():
    """A 20 m path into a 5 m/s headwind (ground speed ~2 m/s at 7 m/s through the air, 10 s
    needed) is flown for the time allowed, the longer of 1.5 x 20 m / 7 m/s and 20 m / 3 m/s
    (MIN_WAY_SPEED), plus 5 reference wingbeats: 7.20 s, and stops within one wingbeat of it
    (a learned wingbeat lasts 0.09-0.115 s) short of the end."""
    from flapsim.bird.tasks.flight_tasks import MIN_WAY_SPEED, REFERENCE_PERIOD_S, Task, fly_task
    from flapsim.bird.tasks.path_shapes import straight

    assert MIN_WAY_SPEED == 3.0
    r = fly_task(Task(straight(20.0), wind=(-5.0, 0.0, 0.0)))
    budget = max(1.5 * 20.0 / 7.0, 20.0 / 3.0) + 5 * REFERENCE_PERIOD_S
    assert r.metrics["progress_m"] < 20.0 and r.status == "lost"
    assert budget - 1e-9 <= r.metrics["simulated_s"] < budget + 0.12
    # what was made good: the progress over the time flown
    assert r.metrics["way_speed_m_s"] == pytest.approx(r.metrics["progress_m"] / r.metrics["simulated_s"])


def test_the_dove_holds_its_airspeed_in_a_crosswind_and_rides_out_a_side_gust():
    """A 2 m/s crosswind across 20 m of straight path: crabbed at 7 m/s airspeed the ground
    speed is sqrt(7^2 - 2^2) = 6.7 m/s; the dove, which makes 6.5 m/s good over the same
    20 m in still air (the start's transient included), must make more than 5.8 m/s good
    (with the trim measured in the wind it slowed to 4.5-5 m/s, 4.6-5.1 over these 20 m).
    And a 3 m/s 1-cosine side gust of 0.5 s on a 25 m path: carried and brought back, it
    completes the path within 2 m (crabbing into each wingbeat's wind it rolled to 60 deg
    and left the 3 m tube 1.5 s after the gust). The straight flights end up to 1.3 m from
    the path in still air too, hence no tighter bound there."""
    from flapsim.bird.tasks.flight_tasks import Task, fly_task
    from flapsim.bird.tasks.path_shapes import straight
    from flapsim.fluid.flow import Gust

    r = fly_task(Task(straight(20.0), wind=(0.0, 2.0, 0.0)))
    assert r.status == "completed"
    assert 20.0 / r.metrics["simulated_s"] > 5.8
    r = fly_task(Task(straight(25.0), flow=(Gust((0.0, 1.0, 0.0), 3.0, 1.0, 0.5),)))
    assert r.status == "completed" and r.metrics["max_path_distance"] < 2.0


def test_speed_first_finishes_a_7_deg_climb_sooner_and_both_make_way():
    """80 m at 7 deg (the bundled database): giving up 0.05 rad of climb per m/s of missing
    airspeed, the dove is at the end within 1.5 x its flight time at 7 m/s (1.5 x 80 / 7 + 5 x
    0.1075 = 17.7 s, the clock that tasks once allowed); with independent
    speed and height loops it slows under the growing climb requests and makes way more slowly,
    though still faster than the 3 m/s the clock now allows for.
    Measured with the regression's wingbeats flown as answered (``refine=0``, as when speed
    first was measured). Over four starts under 1 mm/s apart: speed first 15.7-16.4 s,
    1.6-2.6 m off at most, 4.89-5.10 m/s of way; independent loops 4.43-4.69 m/s of way. Their
    verdict is a coin toss at the tube's edge (3.0-3.2 m off on three of the four, within it
    on other machines), so it is not asserted: the way made is."""
    from flapsim.bird.tasks.flight_tasks import MIN_WAY_SPEED, Task, fly_task
    from flapsim.bird.tasks.path_control import FlightPath
    from flapsim.bird.tasks.path_shapes import START_HEIGHT

    a = np.radians(7.0)
    path = FlightPath(np.array([[0.0, 0.0, START_HEIGHT],
                                [80 * np.cos(a), 0.0, START_HEIGHT + 80 * np.sin(a)]]))
    old_clock = 1.5 * 80.0 / 7.0 + 5 * 0.1075
    first = fly_task(Task(path, climb_per_speed_deficit=0.05), refine=0)
    # at the end; its tube verdict is not asserted either: 1.6-2.6 m off at most over four
    # starts on each of two machines, 0.4 m from the 3 m tube's edge
    assert first.metrics["progress_m"] == pytest.approx(80.0, abs=0.5), first.reason
    assert first.metrics["simulated_s"] < old_clock
    loops = fly_task(Task(path, climb_per_speed_deficit=0.0), refine=0)
    assert loops.metrics["progress_m"] == pytest.approx(80.0, abs=0.5)
    assert MIN_WAY_SPEED < loops.metrics["way_speed_m_s"] < first.metrics["way_speed_m_s"]


def test_the_held_out_user_paths_are_the_helices_and_turns_they_are_named_for():
    # closed form: a helix of radius R climbing at angle g has curvature cos(g)^2 / R and a
    # constant climb g; away from the natural spline's ends it is within 0.5 % (48 points a
    # turn, as above). Sides: a left turn from heading +x goes to +y. Every path is inside the
    # envelope the issue promises (turn radius >= 3 m, climb <= 30 deg) where it is not bent
    # by the spline's ends, and none is a scenario's shape.
    from flapsim.bird.tasks.path_shapes import USER_PATHS

    helices = {"circle-3-left": (3, 0, 1), "circle-3-right": (3, 0, -1), "circle-4-left": (4, 0, 1),
               "circle-4-right": (4, 0, -1), "helix-3-up-3-right": (3, 3, -1),
               "helix-4-up-5": (4, 5, 1), "helix-5-up-8": (5, 8, 1),
               "helix-3-down-10-right": (3, -10, -1)}
    assert set(USER_PATHS) == set(helices) | {"s-curve-3.5", "climb-then-turn"}
    for name, (R, climb, side) in helices.items():
        path = USER_PATHS[name]()
        s = np.linspace(0.25, 0.75, 50) * path.length
        np.testing.assert_allclose(path.curvature(s), np.cos(np.radians(climb)) ** 2 / R, rtol=5e-3,
                                   err_msg=name)
        t = path.tangent(s)
        np.testing.assert_allclose(np.degrees(np.arcsin(t[:, 2])), climb, atol=0.05, err_msg=name)
        np.testing.assert_allclose(path.tangent(0.0)[:2], [1.0, 0.0], atol=0.05, err_msg=name)
        assert np.sign(path.point(0.25 * path.length)[1]) == side, name
    s_path = USER_PATHS["s-curve-3.5"]()
    mid = np.array([0.3, 0.7]) * s_path.length  # one point in each half circle
    np.testing.assert_allclose(s_path.curvature(mid), 1 / 3.5, rtol=0.02)
    climb = USER_PATHS["climb-then-turn"]().geometry()
    assert climb.max_climb_deg <= 30.0 and climb.min_radius_m >= 3.0


def test_a_start_speed_change_changes_the_starts_speed_and_nothing_else(monkeypatch):
    # verdict-spread studies perturb the start along its velocity: the speed by exactly dv
    # (to rounding), the direction and the position not at all
    from flapsim.bird.tasks import flight_tasks as tasks
    from flapsim.bird.tasks.path_shapes import helix

    seen = []

    def capture(fl, ctl, target, task, record, progress):
        seen.append((fl.data.qpos[0:3].copy(), fl.data.qvel[0:3].copy()))
        raise RuntimeError("seen")

    monkeypatch.setattr(tasks, "_fly", capture)
    path = helix(4.0, 5.0, 1.0)
    fl, ctl = tasks.build_flight(tasks.Task(path))
    try:
        for dv in (0.0, 0.25, -1e-3):
            with pytest.raises(RuntimeError, match="seen"):
                tasks.fly_task(tasks.Task(path, start_speed_change=dv), controller=ctl)
    finally:
        fl.close()
    (p0, v0), (p1, v1), (p2, v2) = seen
    assert np.linalg.norm(v1) - np.linalg.norm(v0) == pytest.approx(0.25, abs=1e-12)
    assert np.linalg.norm(v2) - np.linalg.norm(v0) == pytest.approx(-1e-3, abs=1e-12)
    np.testing.assert_allclose(v1 / np.linalg.norm(v1), v0 / np.linalg.norm(v0), atol=1e-12)
    np.testing.assert_array_equal(p1, p0)
    for bad in (float("nan"), 1.5, "0.1", True):
        with pytest.raises(InputError, match="start's speed change"):
            tasks.Task(path, start_speed_change=bad)


def test_a_point_past_the_paths_end_is_off_it_by_its_distance_from_the_ends_line():
    # a straight level line along +x ending at x = 60: a bird 1.3 m past the end, 0.3 m to the
    # side and 0.4 m below is 0.5 m off the line (3-4-5), not sqrt(1.3^2 + 0.5^2) = 1.39 m from
    # the end point; before the end the plain distance holds; a point behind the start is
    # measured to the start point (the extension is the end's only)
    from flapsim.bird.tasks.path_shapes import START_HEIGHT, straight

    path = straight(60.0)
    z = START_HEIGHT
    assert path.off_path(np.array([61.3, 0.3, z - 0.4])) == pytest.approx(0.5, abs=1e-6)
    assert path.distance(np.array([61.3, 0.3, z - 0.4])) == pytest.approx(np.hypot(1.3, 0.5), abs=5e-3)
    # along the path the distance is to its samples (spaced well under 0.1 m): 5 mm
    assert path.off_path(np.array([30.0, 0.3, z - 0.4])) == pytest.approx(0.5, abs=5e-3)
    assert path.off_path(np.array([-1.0, 0.0, z])) == pytest.approx(1.0, abs=5e-3)
