"""The bundled synthetic capture, mirroring, and the BVH/CSV loaders."""

import numpy as np
import pytest

from flapsim.bird.body.params import DOF_NAMES, MIRROR_PERM
from flapsim.bird.flight.capture import (
    DATA_FILE,
    CaptureSet,
    load_capture,
    reference_capture,
    write_bvh,
    write_csv,
)
from flapsim.core.errors import DataFileError, InputError


@pytest.fixture(scope="module")
def cap():
    return reference_capture()


def test_reference_set_is_labelled_synthetic_and_covers_the_paper_ranges(cap):
    assert cap.synthetic and "SYNTHETIC" in cap.source
    assert cap.rate_hz == 240.0
    assert 140 <= cap.n_cycles <= 160  # the paper's capture set: ~150 wingbeats
    assert cap.with_mirror().n_cycles == 2 * cap.n_cycles
    # the paper's capture ranges (sec. 7), reached exactly by construction (1e-9: float)
    assert cap.steering_deg.min() == pytest.approx(-12.5) and cap.steering_deg.max() == \
        pytest.approx(7.0)
    assert cap.elevation_deg.min() == pytest.approx(-5.0) and cap.elevation_deg.max() == \
        pytest.approx(5.8)
    assert cap.speed.min() == pytest.approx(2.0) and cap.speed.max() == pytest.approx(5.1)
    f = 1.0 / cap.durations
    assert f.min() >= 8.0 and f.max() <= 11.0  # paper: 8-11 Hz


def test_mean_cycle_has_a_55_percent_downstroke(cap):
    flap = cap.cycle_matrix(200).mean(axis=0)[:, DOF_NAMES.index("l_shoulder_flap")]
    bottom = np.argmin(flap) / 200
    # generator: 55%; the mean of 300 noisy cycles lands within one 1/200 sample + blending
    assert bottom == pytest.approx(0.55, abs=0.03)
    amp = np.degrees(np.ptp(flap))
    assert 100 <= amp <= 140  # slow-flight stroke amplitude (REFERENCE_DATA)


def test_mirror_swaps_sides_and_is_an_involution(cap):
    m = cap.mirror()
    assert np.array_equal(m.angles, cap.angles[:, MIRROR_PERM])
    assert np.array_equal(m.steering_deg, -cap.steering_deg)
    assert np.array_equal(m.mirror().angles, cap.angles)
    assert m.mirrored.all() and not m.mirror().mirrored.any()


def test_csv_round_trip(tmp_path, cap):
    n = int(cap.cycle_end[5]) + 2
    path = tmp_path / "take.csv"
    write_csv(path, cap.angles[:n], cap.rate_hz)
    real = load_capture(path)
    assert not real.synthetic and np.isnan(real.steering_deg).all()
    # 6 decimals of a degree in the file -> 1e-8 rad
    assert np.allclose(real.angles, cap.angles[:n], atol=1e-7)
    # the segmentation finds the stored cycle starts again (sub-frame, from the same data)
    common = real.cycle_start[:4]
    assert np.allclose(common, cap.cycle_start[1:5], atol=1e-6) or np.allclose(
        common, cap.cycle_start[:4], atol=1e-6)


def test_bvh_round_trip(tmp_path, cap):
    n = int(cap.cycle_end[3]) + 2
    path = tmp_path / "take.bvh"
    write_bvh(path, cap.angles[:n], cap.rate_hz)
    real = load_capture(path)
    assert real.rate_hz == pytest.approx(240.0, rel=1e-6)
    # Euler angles written with 6 decimals of a degree: 1e-7 rad, times a few for re-composition
    assert np.allclose(real.angles, cap.angles[:n], atol=1e-6)
    assert real.n_cycles >= 2


@pytest.mark.parametrize("text, match", [
    ("time_s,l_shoulder_flap_deg\n0,1\n0.1,2\n", "missing column"),
    ("time_s," + ",".join(f"{d}_deg" for d in DOF_NAMES) + "\n" + "0," + ",".join(["1"] * 14)
     + "\n0.1," + ",".join(["x"] * 14) + "\n0.2," + ",".join(["1"] * 14) + "\n", "line 3"),
])
def test_malformed_csv_gives_one_line_naming_the_file(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataFileError, match=match) as err:
        load_capture(path)
    assert str(path) in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("cut, match", [(0.5, "malformed BVH|numbers"), (0.2, "malformed|no BVH")])
def test_malformed_bvh_gives_one_line_naming_the_file(tmp_path, cap, cut, match):
    good = tmp_path / "good.bvh"
    write_bvh(good, cap.angles[:60], cap.rate_hz)
    text = good.read_text()
    bad = tmp_path / "bad.bvh"
    bad.write_text(text[: int(len(text) * cut)])
    with pytest.raises(DataFileError, match=match) as err:
        load_capture(bad)
    assert str(bad) in str(err.value) and "\n" not in str(err.value)


def test_foreign_npz_is_refused(tmp_path):
    path = tmp_path / "x.npz"
    np.savez(path, a=np.zeros(3))
    with pytest.raises(DataFileError, match="not a flapsim.capture"):
        load_capture(path)


def test_bundled_file_has_provenance():
    with np.load(DATA_FILE, allow_pickle=False) as z:
        assert str(z["generator"]) == "flapsim.bird.flight.synthetic_capture.synthesize"
        assert int(z["seed"]) == 2013 and bool(z["synthetic"])


def test_capture_set_checks_shapes():
    with pytest.raises(Exception, match="one value per cycle"):
        CaptureSet(np.zeros((10, 14)), 240.0, [0.0], [5.0, 6.0], [0.0], [0.0], [0.0], True, "")


def test_the_cruise_capture_is_a_cruise_stroke_over_the_cruise_ranges():
    from flapsim.bird.body.model import wingspan
    from flapsim.bird.body.params import DoveParams

    cap = reference_capture(preset="cruise")
    assert cap.synthetic and 140 <= cap.n_cycles <= 160
    # the paper's turns and climbs, reached exactly by construction; speeds over 5-10 m/s and more
    assert cap.steering_deg.min() == pytest.approx(-12.5) and cap.steering_deg.max() == \
        pytest.approx(7.0)
    assert cap.elevation_deg.min() == pytest.approx(-5.0) and cap.elevation_deg.max() == \
        pytest.approx(5.8)
    assert cap.speed.min() <= 5.0 and cap.speed.max() >= 10.0
    # Pennycuick's cruise frequency for this dove, 8.3 Hz; birds fly at 0.81-1.05 of it, the
    # cycles' own variation (3 % noise, speed) adds a little either side
    f = 1.0 / cap.durations
    assert f.min() >= 0.75 * 8.3 and f.max() <= 1.15 * 8.3
    flap = cap.cycle_matrix(200).mean(axis=0)[:, DOF_NAMES.index("l_shoulder_flap")]
    # cruising doves: downstroke 50-55 % of the cycle (0.01 either side: 1/200 sampling, blending)
    assert 0.49 <= np.argmin(flap) / 200 <= 0.56
    # Strouhal number f A / V at the mean speed, A the tip's vertical excursion of a straight
    # half span: cruising birds 0.2-0.4 (Taylor, Nudds & Thomas 2003)
    excursion = 0.5 * wingspan(DoveParams.load()) * (np.sin(flap.max()) - np.sin(flap.min()))
    st = excursion / (cap.durations.mean() * cap.speed.mean())
    assert 0.2 <= st <= 0.4
    with pytest.raises(InputError, match="unknown capture"):
        reference_capture(preset="fast")
