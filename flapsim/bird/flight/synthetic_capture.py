"""The generator of the bundled SYNTHETIC dove capture (there is no public dove capture).

Each wingbeat is a smooth periodic function of phase per DOF, built from published
pigeon/dove kinematics (see :data:`flapsim.bird.flight.capture.SOURCES` and the field docs of
:class:`Kinematics`). Cycle-to-cycle variation follows each cycle's steering, elevation
and speed (random walks within the paper's capture ranges) plus small independent
noise, and the stream is sampled at 240 Hz like the paper's capture:

* speed: slower flight -> slightly higher frequency, wider and lower tail, larger
  stroke amplitude (Tobalske & Dial 1996);
* elevation (climb): larger amplitude and more pronation on both wings;
* steering (turn toward +y = left is positive): the outside wing protracts more and
  beats wider, the inside wing is retracted and pronated (Ros et al. 2015).

Regenerate the data file with ``python -m flapsim.bird.flight.synthetic_capture [--seed 2013]
[--out FILE]``; the bundled file is its output (``tests/bird/body/test_build.py`` compares every entry).
"""

from __future__ import annotations

import argparse
from dataclasses import asdict, dataclass

import numpy as np

from flapsim.bird.body.params import DOF_NAMES, N_DOF
from flapsim.bird.flight.capture import CAPTURE_FILES, SOURCES, CaptureSet, segment_cycles
from flapsim.bird.flight.wingbeat import ReferenceWingbeat
from flapsim.core.errors import InputError

_COL = {n: k for k, n in enumerate(DOF_NAMES)}


@dataclass(frozen=True)
class Kinematics:
    """The mean (symmetric) synthetic wingbeat, angles in degrees."""

    speed_m_s: float = 3.5
    """Flight speed these kinematics are flown at, m/s (conditions vary about it)."""
    frequency_hz: float = 9.3
    """Wingbeat frequency at ``speed_m_s`` (paper: 8-11 Hz; pigeon 6.1-9.6 Hz, Berg & Biewener 2008)."""
    downstroke_fraction: float = 0.55
    """Share of the cycle spent in the downstroke (approx. 50-60%, pigeon/dove)."""
    flap_mean_deg: float = 12.0
    """Mean shoulder elevation (stroke centre above horizontal)."""
    flap_amplitude_deg: float = 60.0
    """Half the stroke amplitude (slow flight: 100-140 deg in total)."""
    sweep_mean_deg: float = -4.0
    """Mean wing sweep (+ back); the wing is held slightly protracted."""
    sweep_top_deg: float = 10.0
    """Sweep back at the top / forward at the bottom of the stroke (stroke-plane tilt)."""
    sweep_mid_deg: float = -6.0
    """Extra protraction at mid-downstroke (elliptical tip path)."""
    pronation_deg: float = 4.0
    """Shoulder pronation at mid-downstroke, supination at mid-upstroke (Crandell &
    Tobalske 2011: pronated downstroke, supinated upstroke)."""
    pronation_mean_deg: float = 0.0
    """Mean shoulder twist."""
    elbow_twist_deg: float = 8.0
    """Extra pronation of the forearm at mid-downstroke (the hand wing's twist relative to
    the arm wing; supination at mid-upstroke)."""
    elbow_twist_mean_deg: float = 0.0
    """Mean pronation of the forearm relative to the arm wing."""
    elbow_flex_min_deg: float = 6.0
    """Elbow flexion with the wing spread (downstroke)."""
    elbow_flex_max_deg: float = 55.0
    """Elbow flexion at mid-upstroke (flexed upstroke at low speed, Tobalske & Dial 1996)."""
    wrist_flex_min_deg: float = 4.0
    """Wrist flexion with the wing spread."""
    wrist_flex_max_deg: float = 65.0
    """Wrist flexion at mid-upstroke (primaries fan in)."""
    flex_peak_phase: float = 0.72
    """Warped phase of the largest flexion (mid-upstroke is 0.75)."""
    tail_bend_deg: float = -10.0
    """Mean tail elevation: the captured indoor dove held its tail low (paper sec. 7)."""
    tail_bend_amplitude_deg: float = 3.0
    """Tail bob with the wingbeat."""
    tail_spread_deg: float = 28.0
    """Mean half-fan spread at 3.5 m/s (wide in slow flight, Tobalske & Dial 1996)."""


@dataclass(frozen=True)
class Variation:
    """How per-cycle steering, elevation and speed and noise change the wingbeat."""

    steering_range_deg: tuple[float, float] = (-12.5, 7.0)
    """Heading change per wingbeat (paper's capture, sec. 7)."""
    elevation_range_deg: tuple[float, float] = (-5.0, 5.8)
    """Climb angle change per wingbeat (paper's capture)."""
    speed_range: tuple[float, float] = (2.0, 5.1)
    """Flight speed, m/s (paper's capture)."""
    speed_step_m_s: float = 0.3
    """Standard deviation of the speed's random walk from cycle to cycle, m/s."""
    freq_per_speed: float = -0.25
    """Frequency change per m/s faster, Hz."""
    sweep_per_steer: float = 0.8
    """Inside-wing retraction per degree of turn (outside wing protracts), deg/deg."""
    pronation_per_steer: float = 0.5
    """Inside-wing extra pronation per degree of turn, deg/deg."""
    amplitude_per_steer: float = 0.008
    """Outside-wing amplitude scale per degree of turn."""
    amplitude_per_climb: float = 0.02
    """Amplitude scale per degree of climb (both wings)."""
    pronation_per_climb: float = 0.6
    """Pronation per degree of climb, deg/deg."""
    amplitude_per_speed: float = -0.04
    """Amplitude scale per m/s faster."""
    tail_spread_per_speed: float = -5.0
    """Tail spread per m/s faster, deg."""
    tail_bend_per_climb: float = -0.8
    """Tail elevation per degree of climb, deg/deg."""
    noise_scale: float = 0.03
    """Independent per-cycle amplitude noise (relative)."""
    noise_offset_deg: float = 1.5
    """Independent per-cycle offset noise, deg."""
    noise_frequency: float = 0.03
    """Independent per-cycle period noise (relative)."""
    marker_noise_deg: float = 0.3
    """Per-frame measurement noise, deg."""


#: The paper's capture conditions: slow indoor flight at 2-5 m/s (the dataclasses' defaults;
#: the bundled capture).
SLOW = (Kinematics(), Variation())

#: Cruise: the kinematic model at 8.5 m/s searched by ``studies/dove_cruise_kinematics.py`` for
#: the least servo power at which the free dove holds height and speed (bird-wing section,
#: induced flow), inside published cruise ranges: 7-9.5 Hz (Pennycuick's 8.3 Hz for this dove,
#: birds fly at 0.81-1.05 of it), downstroke 50-56 % of the cycle, Strouhal number <= 0.4
#: (Taylor, Nudds & Thomas 2003), a flexed upstroke; the hand wing twists against the arm wing
#: through the elbow's twist. Conditions vary over 5-12 m/s with the paper's turns and climbs;
#: the frequency barely changes with speed (pigeons 6-20 m/s, Tobalske & Dial 1996).
CRUISE = (
    Kinematics(speed_m_s=8.5, frequency_hz=8.439, downstroke_fraction=0.543, flap_mean_deg=-5.516,
               flap_amplitude_deg=40.634, sweep_mean_deg=0.681, sweep_top_deg=12.550,
               sweep_mid_deg=-9.487, pronation_mean_deg=6.583, pronation_deg=3.821,
               elbow_twist_mean_deg=-2.552, elbow_twist_deg=7.624, elbow_flex_max_deg=45.249,
               wrist_flex_max_deg=31.988, flex_peak_phase=0.690, tail_spread_deg=25.577),
    Variation(speed_range=(5.0, 12.0), speed_step_m_s=0.5, freq_per_speed=-0.05,
              tail_spread_per_speed=-2.0),
)

PRESETS = {"slow": SLOW, "cruise": CRUISE}
"""The generator's kinematics and variation by name, each written to its bundled file
(:data:`flapsim.bird.flight.capture.CAPTURE_FILES`)."""


def warp(phase: np.ndarray, down: float) -> np.ndarray:
    """Map cycle phase to a 'stroke phase' u whose first half is the downstroke."""
    p = np.mod(phase, 1.0)
    return np.where(p < down, 0.5 * p / down, 0.5 + 0.5 * (p - down) / (1.0 - down))


def cycle_angles(phase: np.ndarray, k: Kinematics, steer: float = 0.0, climb: float = 0.0,
                 speed: float | None = None, var: Variation | None = None,
                 noise: np.ndarray | None = None) -> np.ndarray:
    """(n, 14) angles in rad for phases in [0, 1) of one cycle with these conditions.

    ``noise`` is (14, 2): relative amplitude and offset noise (deg) per DOF; ``speed``
    defaults to the kinematics' own.
    """
    var = var or Variation()
    speed = k.speed_m_s if speed is None else speed
    u = warp(np.asarray(phase, float), k.downstroke_fraction)
    c, s = np.cos(2 * np.pi * u), np.sin(2 * np.pi * u)
    flex = 0.5 - 0.5 * np.cos(2 * np.pi * (u - k.flex_peak_phase + 0.5))  # 0 .. 1, peak at u=peak
    out = np.zeros((len(u), N_DOF))
    dv = speed - k.speed_m_s
    for side, turn in (("l", 1.0), ("r", -1.0)):
        # left turn (steer > 0): left wing is the inside wing
        inside = turn * steer
        amp = k.flap_amplitude_deg * (1 - var.amplitude_per_steer * inside
                                      + var.amplitude_per_climb * climb
                                      + var.amplitude_per_speed * dv)
        out[:, _COL[f"{side}_shoulder_flap"]] = k.flap_mean_deg + amp * c
        out[:, _COL[f"{side}_shoulder_sweep"]] = (k.sweep_mean_deg + var.sweep_per_steer * inside
                                                 + k.sweep_top_deg * c + k.sweep_mid_deg * s)
        out[:, _COL[f"{side}_shoulder_twist"]] = (
            k.pronation_mean_deg + var.pronation_per_steer * inside
            + (k.pronation_deg + var.pronation_per_climb * climb) * s)
        out[:, _COL[f"{side}_elbow_flex"]] = (k.elbow_flex_min_deg
                                             + (k.elbow_flex_max_deg - k.elbow_flex_min_deg) * flex)
        out[:, _COL[f"{side}_elbow_twist"]] = k.elbow_twist_mean_deg + k.elbow_twist_deg * s
        out[:, _COL[f"{side}_wrist_flex"]] = (k.wrist_flex_min_deg
                                             + (k.wrist_flex_max_deg - k.wrist_flex_min_deg) * flex)
    out[:, _COL["tail_bend"]] = (k.tail_bend_deg + var.tail_bend_per_climb * climb
                                 + k.tail_bend_amplitude_deg * c)
    out[:, _COL["tail_spread"]] = k.tail_spread_deg + var.tail_spread_per_speed * dv + 2.0 * c
    if noise is not None:
        mean = out.mean(axis=0)
        out = mean + (out - mean) * (1 + noise[:, 0]) + noise[:, 1]
    return np.radians(out)


def kinematic_reference(kin: Kinematics, n_phase: int = 96) -> ReferenceWingbeat:
    """The reference wingbeat of kinematics ``kin`` flown straight and level at its own speed
    without noise: what averaging many symmetric capture cycles of it converges to."""
    cycle = cycle_angles(np.arange(n_phase) / n_phase, kin)
    return ReferenceWingbeat.from_cycle(cycle, 1.0 / kin.frequency_hz)


def _walk(rng: np.random.Generator, n: int, lo: float, hi: float, step: float) -> np.ndarray:
    """A reflected random walk inside [lo, hi]."""
    x = np.empty(n)
    x[0] = rng.uniform(lo, hi)
    for i in range(1, n):
        v = x[i - 1] + rng.normal(0, step)
        while v < lo or v > hi:
            v = 2 * lo - v if v < lo else 2 * hi - v
        x[i] = v
    return x


def synthesize(seed: int = 2013, takes: int = 10, cycles_per_take: int = 15, rate_hz: float = 240.0,
               kin: Kinematics | None = None, var: Variation | None = None) -> CaptureSet:
    """A synthetic capture: ``takes`` continuous flights of ``cycles_per_take`` wingbeats.

    Conditions per cycle are random walks inside the paper's ranges; the extremes of
    each range are visited (the first cycles of the first takes are set to them) so
    the set covers the full ranges. Cycle bounds come from :func:`segment_cycles`, as
    they would for real data; cycles are labelled with the conditions they were made with.
    """
    kin = kin or Kinematics()
    var = var or Variation()
    rng = np.random.default_rng(seed)
    frames, starts, ends, steer_l, elev_l, speed_l = [], [], [], [], [], []
    offset = 0
    extremes = [(var.steering_range_deg[0], None, None), (var.steering_range_deg[1], None, None),
                (None, var.elevation_range_deg[0], None), (None, var.elevation_range_deg[1], None),
                (None, None, var.speed_range[0]), (None, None, var.speed_range[1])]
    for take in range(takes):
        n = cycles_per_take + 2  # one spare cycle each end: segmentation needs the next top
        steer = _walk(rng, n, *var.steering_range_deg, 2.5)
        elev = _walk(rng, n, *var.elevation_range_deg, 1.5)
        speed = _walk(rng, n, *var.speed_range, var.speed_step_m_s)
        if take < len(extremes):
            a, b, c = extremes[take]
            steer[3] = a if a is not None else steer[3]
            elev[3] = b if b is not None else elev[3]
            speed[3] = c if c is not None else speed[3]
        period = 1.0 / (kin.frequency_hz + var.freq_per_speed * (speed - kin.speed_m_s))
        period *= 1 + rng.normal(0, var.noise_frequency, n)
        noise = np.stack([rng.normal(0, var.noise_scale, (n, N_DOF)),
                          rng.normal(0, var.noise_offset_deg, (n, N_DOF))], axis=2)
        bounds = np.concatenate([[0.0], np.cumsum(period)])
        t0 = rng.uniform(0, period[0])  # capture starts mid-cycle
        t = np.arange(t0, bounds[-1], 1.0 / rate_hz)
        cyc = np.clip(np.searchsorted(bounds, t, side="right") - 1, 0, n - 1)
        phase = (t - bounds[cyc]) / period[cyc]
        ang = np.empty((len(t), N_DOF))
        # blend each cycle into the next over the last 20% so the stream stays smooth
        for i in range(n):
            sel = cyc == i
            if not sel.any():
                continue
            a_i = cycle_angles(phase[sel], kin, steer[i], elev[i], speed[i], var, noise[i])
            if i + 1 < n:
                a_n = cycle_angles(phase[sel], kin, steer[i + 1], elev[i + 1], speed[i + 1], var,
                                   noise[i + 1])
                wgt = np.clip((phase[sel] - 0.8) / 0.2, 0, 1)
                wgt = (wgt * wgt * (3 - 2 * wgt))[:, None]
                a_i = (1 - wgt) * a_i + wgt * a_n
            ang[sel] = a_i
        ang += np.radians(rng.normal(0, var.marker_noise_deg, ang.shape))
        s, e = segment_cycles(ang, rate_hz)
        # label each found cycle with the conditions of the generator cycle it lies in
        mid_t = t0 + (0.5 * (s + e)) / rate_hz
        idx = np.clip(np.searchsorted(bounds, mid_t, side="right") - 1, 0, n - 1)
        keep = np.argsort(np.abs(idx - (n - 1) / 2))[:cycles_per_take]
        keep.sort()
        frames.append(ang)
        starts.append(s[keep] + offset)
        ends.append(e[keep] + offset)
        steer_l.append(steer[idx[keep]])
        elev_l.append(elev[idx[keep]])
        speed_l.append(speed[idx[keep]])
        offset += len(ang)
    source = ("SYNTHETIC dove wingbeats made by flapsim.bird.flight.synthetic_capture.synthesize(seed="
              f"{seed}) from published kinematics: " + "; ".join(SOURCES))
    return CaptureSet(np.vstack(frames), rate_hz, np.concatenate(starts), np.concatenate(ends),
                      np.concatenate(steer_l), np.concatenate(elev_l), np.concatenate(speed_l),
                      True, source)


def write_reference(path=None, seed: int = 2013, preset: str = "slow") -> CaptureSet:
    """Write the synthetic capture of ``preset`` (:data:`PRESETS`) drawn with ``seed`` (default
    path: the preset's bundled file)."""
    if preset not in PRESETS:
        raise InputError(f"unknown capture preset {preset!r}; choose one of {', '.join(PRESETS)}")
    k, v = PRESETS[preset]
    cap = synthesize(seed, kin=k, var=v)
    cap.save(CAPTURE_FILES[preset] if path is None else path,
             generator=np.array("flapsim.bird.flight.synthetic_capture.synthesize"),
             seed=np.array(seed), preset=np.array(preset), kinematics=np.array(repr(asdict(k))),
             variation=np.array(repr(asdict(v))))
    return cap


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description="Regenerate the bundled synthetic dove capture.")
    ap.add_argument("--seed", type=int, default=2013, help="the draw (default 2013, the bundled one's)")
    ap.add_argument("--out", default=None, help="output .npz (default: the preset's bundled file)")
    ap.add_argument("--preset", choices=tuple(PRESETS), default="slow",
                    help="slow (the paper's capture conditions, 2-5 m/s: the default capture) or "
                         "cruise (5-12 m/s around the cruise wingbeat)")
    args = ap.parse_args(argv)
    cap = write_reference(args.out, args.seed, args.preset)
    args.out = args.out or str(CAPTURE_FILES[args.preset])
    f = 1.0 / cap.durations
    amp = np.degrees(np.ptp(cap.cycle_matrix()[:, :, 0], axis=1))
    print(f"wrote {args.out}: {cap.n_cycles} cycles, {len(cap.angles)} frames at {cap.rate_hz} Hz")
    print(f"wingbeat {f.min():.2f}-{f.max():.2f} Hz (mean {f.mean():.2f}); steering "
          f"{cap.steering_deg.min():.1f}..{cap.steering_deg.max():.1f} deg, elevation "
          f"{cap.elevation_deg.min():.1f}..{cap.elevation_deg.max():.1f} deg, speed "
          f"{cap.speed.min():.2f}..{cap.speed.max():.2f} m/s; stroke amplitude "
          f"{amp.min():.0f}-{amp.max():.0f} deg")


if __name__ == "__main__":
    main()
