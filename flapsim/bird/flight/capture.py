"""Wingbeat capture data on the dove's 14 DOF: the bundled SYNTHETIC reference set, loaders
for real capture (BVH, CSV), cycle segmentation and mirroring.

There is no public dove motion capture (the flight paper's 152 cycles are not
published), so flapsim ships a synthetic set made by :func:`synthesize` from published
pigeon/dove kinematics (sources in :data:`SOURCES`): wingbeat 8-11 Hz, downstroke ~55%
of the cycle, stroke amplitude ~120 deg, pronated downstroke, flexed and supinated
upstroke, with cycle-to-cycle variation tied to per-cycle steering (-12.5..7.0 deg per
wingbeat), elevation (-5.0..5.8 deg) and speed (2.0..5.1 m/s), the ranges the paper
reports for its capture (sec. 7). Its metadata says ``synthetic = True``. A user with
real capture loads it with :func:`load_capture` (``.bvh``, ``.csv`` or flapsim ``.npz``)
and trains the same way.

Conventions: angles in radians in the order of :data:`flapsim.bird.body.params.DOF_NAMES`
(mirror symmetric: equal left/right values are a symmetric pose). A cycle starts at the
top of the wingbeat (largest mean shoulder elevation), i.e. at the start of the
downstroke. Cycle bounds are fractional frame indices.

CSV format: a header row, then one row per frame. Columns: ``time_s`` and one column per
DOF named ``<dof>_deg`` (e.g. ``l_shoulder_flap_deg``), angles in degrees; extra columns
are ignored. Frames must be evenly spaced.

BVH: a standard Biovision file whose skeleton uses flapsim's axes at rest (x forward,
y left, z up, wings straight out along +-y). Joints are found by name (case-insensitive,
see :data:`BVH_JOINTS`); each joint's rotation (channels in any order, degrees) is
decomposed into the model's hinge sequence (shoulder x-z-y, elbow z-y, wrist z; tail bend
about y on the tail joint, spread about z on the left tail-fan joint).
"""

from __future__ import annotations

import csv
import logging
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from flapsim.bird.body.params import DOF_NAMES, MIRROR_PERM, N_DOF
from flapsim.core.errors import DataFileError, InputError
from flapsim.core.io import save_npz
from flapsim.core.validate import require_finite

log = logging.getLogger(__name__)

SCHEMA = "flapsim.capture/1"
DATA_FILE = Path(__file__).resolve().parent / "data" / "dove_capture_synthetic.npz"
#: The bundled synthetic captures by preset (``flapsim.bird.flight.synthetic_capture``): the
#: paper's slow-flight conditions (the default) and the cruise around the trimmed wingbeat
CAPTURE_FILES = {"slow": DATA_FILE, "cruise": DATA_FILE.with_name("dove_capture_cruise.npz")}

SOURCES = (
    "Ju, Won, Lee, Noh, Kim, Lee: Data-driven control of flapping flight, ACM TOG 32(5) 2013 "
    "(240 Hz capture, 152 cycles; steering -12.5..7.0 deg/wingbeat, elevation -5.0..5.8 deg, "
    "speed 2.0..5.1 m/s; wingbeat 8-11 Hz; Fig. 5 joint curves)",
    "Tobalske & Dial 1996 JEB 199:263 (pigeon kinematics: near-constant frequency, tail spread "
    "and stroke-plane angle fall with speed; flexed upstroke at low speed)",
    "Berg & Biewener 2008 JEB 211:1120 (pigeon 6.1-9.6 Hz, 2.9-4.9 m/s)",
    "Ros, Bassman, Badger, Pierson, Biewener 2011 PNAS 108:19990; Ros et al. 2015 JEB 218:480 "
    "(turns by banking; outside wing protracts more, inside wing retracted and pronated)",
    "Crandell & Tobalske 2011 JEB 214:1867 (rock dove: pronated downstroke AoA ~46 deg, "
    "supinated upstroke)",
    "Hedrick, Tobalske & Biewener 2002 JEB 205:1389 (ringed turtle-dove kinematics vs speed)",
)


@dataclass(frozen=True)
class CaptureSet:
    """Joint-angle capture of wingbeats on the 14 DOF."""

    angles: np.ndarray
    """(n_frames, 14) joint angles, rad."""
    rate_hz: float
    """Frame rate, Hz."""
    cycle_start: np.ndarray
    """(n_cycles,) fractional frame index where each cycle starts (top of the wingbeat)."""
    cycle_end: np.ndarray
    """(n_cycles,) fractional frame index where it ends."""
    steering_deg: np.ndarray
    """(n_cycles,) heading change per wingbeat, deg (+ left); NaN when unknown."""
    elevation_deg: np.ndarray
    """(n_cycles,) climb angle change per wingbeat, deg (+ up); NaN when unknown."""
    speed: np.ndarray
    """(n_cycles,) flight speed, m/s; NaN when unknown."""
    synthetic: bool
    """True for generated data (the bundled set), False for real capture."""
    source: str
    """Where the data came from (file, generator and literature)."""
    mirrored: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    """(n_cycles,) True for cycles made by mirroring another."""

    def __post_init__(self) -> None:
        a = np.asarray(self.angles, dtype=float)
        if a.ndim != 2 or a.shape[1] != N_DOF:
            raise InputError(f"capture angles must be (n_frames, {N_DOF}), got {a.shape}")
        object.__setattr__(self, "angles", a)
        n = len(np.asarray(self.cycle_start))
        for name in ("cycle_start", "cycle_end", "steering_deg", "elevation_deg", "speed"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (n,):
                raise InputError(f"capture {name} must have one value per cycle ({n})")
            object.__setattr__(self, name, v)
        mir = np.asarray(self.mirrored, dtype=bool)
        object.__setattr__(self, "mirrored", mir if mir.shape == (n,) else np.zeros(n, bool))

    @property
    def n_cycles(self) -> int:
        return len(self.cycle_start)

    @property
    def durations(self) -> np.ndarray:
        """Cycle durations, s."""
        return (self.cycle_end - self.cycle_start) / self.rate_hz

    def cycle_matrix(self, n_phase: int = 64) -> np.ndarray:
        """(n_cycles, n_phase, 14): each cycle resampled at phases j / n_phase (phase-aligned)."""
        frames = np.arange(len(self.angles))
        out = np.empty((self.n_cycles, n_phase, N_DOF))
        phase = np.arange(n_phase) / n_phase
        for c, (s, e) in enumerate(zip(self.cycle_start, self.cycle_end, strict=True)):
            t = s + phase * (e - s)
            for j in range(N_DOF):
                out[c, :, j] = np.interp(t, frames, self.angles[:, j])
        return out

    def mirror(self) -> CaptureSet:
        """The mirror image: left and right swapped, steering negated."""
        return replace(self, angles=self.angles[:, MIRROR_PERM], steering_deg=-self.steering_deg,
                       mirrored=~self.mirrored, source=self.source + " (mirrored)")

    def with_mirror(self) -> CaptureSet:
        """These cycles followed by their mirror images (the paper's 152 -> 304)."""
        m = self.mirror()
        off = len(self.angles)
        return CaptureSet(
            np.vstack([self.angles, m.angles]), self.rate_hz,
            np.concatenate([self.cycle_start, m.cycle_start + off]),
            np.concatenate([self.cycle_end, m.cycle_end + off]),
            np.concatenate([self.steering_deg, m.steering_deg]),
            np.concatenate([self.elevation_deg, m.elevation_deg]),
            np.concatenate([self.speed, m.speed]), self.synthetic, self.source + " + mirror",
            np.concatenate([self.mirrored, m.mirrored]),
        )

    def save(self, path: str | Path, **extra: object) -> None:
        """Write the flapsim ``.npz`` capture format (atomically, no pickles)."""
        save_npz(
            path, schema=np.array(SCHEMA), angles=self.angles.astype(np.float32),
            rate_hz=np.array(self.rate_hz), cycle_start=self.cycle_start, cycle_end=self.cycle_end,
            steering_deg=self.steering_deg, elevation_deg=self.elevation_deg, speed=self.speed,
            synthetic=np.array(self.synthetic), source=np.array(self.source),
            mirrored=self.mirrored, dof_names=np.array(DOF_NAMES),
            **{k: np.asarray(v) for k, v in extra.items()},
        )


# -- loading -------------------------------------------------------------------------------


def reference_capture(with_mirror: bool = False, preset: str = "slow") -> CaptureSet:
    """A bundled synthetic capture (~150 cycles; ~300 with ``with_mirror``): the paper's
    slow-flight conditions, or ``preset="cruise"``."""
    if preset not in CAPTURE_FILES:
        raise InputError(f"unknown capture {preset!r}; choose one of {', '.join(CAPTURE_FILES)}")
    cap = load_capture(CAPTURE_FILES[preset])
    return cap.with_mirror() if with_mirror else cap


def load_capture(path: str | Path) -> CaptureSet:
    """Load ``.npz`` (flapsim format), ``.bvh`` or ``.csv`` capture onto the 14 DOF."""
    path = Path(path)
    if not path.exists():
        raise DataFileError(f"capture file {path} does not exist")
    suffix = path.suffix.lower()
    if suffix == ".npz":
        return _load_npz(path)
    if suffix == ".bvh":
        angles, rate = read_bvh(path)
    elif suffix == ".csv":
        angles, rate = read_csv(path)
    else:
        raise DataFileError(f"capture file {path}: unknown format {suffix!r} (use .bvh, .csv, .npz)")
    start, end = segment_cycles(angles, rate)
    if len(start) == 0:
        raise DataFileError(f"capture file {path}: no complete wingbeat found (need >= 2 tops of "
                            "the shoulder elevation, 8-11 Hz wingbeats)")
    nan = np.full(len(start), np.nan)
    return CaptureSet(angles, rate, start, end, nan, nan.copy(), nan.copy(), False, str(path))


def _load_npz(path: Path) -> CaptureSet:
    try:
        with np.load(path, allow_pickle=False) as z:
            if "schema" not in z or str(z["schema"]) != SCHEMA:
                raise DataFileError(f"capture file {path} is not a {SCHEMA} file")
            if tuple(str(s) for s in z["dof_names"]) != DOF_NAMES:
                raise DataFileError(f"capture file {path}: DOF names differ from the dove model's")
            require_finite({k: z[k] for k in ("angles", "rate_hz", "cycle_start", "cycle_end")},
                           f"capture file {path}")
            # NaN is a cycle without a label (a BVH or CSV capture has none); sampling refuses
            # it where it needs labels, and an infinity is no label at all
            require_finite({k: np.where(np.isnan(z[k]), 0.0, z[k])
                            for k in ("steering_deg", "elevation_deg", "speed")},
                           f"capture file {path}", fix="a label is a finite number, or NaN for a "
                           "cycle without one")
            return CaptureSet(
                z["angles"].astype(float), float(z["rate_hz"]), z["cycle_start"], z["cycle_end"],
                z["steering_deg"], z["elevation_deg"], z["speed"], bool(z["synthetic"]),
                str(z["source"]), z["mirrored"],
            )
    except (OSError, ValueError, KeyError) as exc:
        raise DataFileError(f"capture file {path} is unreadable: {exc}") from None


def segment_cycles(angles: np.ndarray, rate_hz: float, min_hz: float = 4.0, max_hz: float = 20.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Split a stream into wingbeats at the tops of the mean shoulder elevation.

    Tops are local maxima at least ``1/max_hz`` apart, refined to sub-frame time by a
    parabola through the three samples; a cycle runs from one top to the next if it
    lasts at most ``1/min_hz``.
    """
    flap = 0.5 * (angles[:, DOF_NAMES.index("l_shoulder_flap")]
                  + angles[:, DOF_NAMES.index("r_shoulder_flap")])
    gap = max(1, int(rate_hz / max_hz))
    tops = []
    for i in range(1, len(flap) - 1):
        lo, hi = max(0, i - gap), min(len(flap), i + gap + 1)
        if flap[i] >= flap[lo:hi].max() and flap[i] > flap[i - 1]:
            y0, y1, y2 = flap[i - 1], flap[i], flap[i + 1]
            den = y0 - 2 * y1 + y2
            tops.append(i + (0.5 * (y0 - y2) / den if den < 0 else 0.0))
    tops = np.array(tops)
    if len(tops) < 2:
        return np.zeros(0), np.zeros(0)
    dur = np.diff(tops) / rate_hz
    ok = dur <= 1.0 / min_hz
    return tops[:-1][ok], tops[1:][ok]


def read_csv(path: str | Path) -> tuple[np.ndarray, float]:
    """Angles (n, 14) in rad and the frame rate from a flapsim joint-angle CSV."""
    path = Path(path)
    try:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(f"capture file {path} is unreadable: {exc}") from None
    if len(rows) < 3:
        raise DataFileError(f"capture file {path}: needs a header row and at least 2 frames")
    header = [h.strip() for h in rows[0]]
    need = ["time_s"] + [f"{n}_deg" for n in DOF_NAMES]
    missing = [c for c in need if c not in header]
    if missing:
        raise DataFileError(f"capture file {path}: missing column(s) {', '.join(missing)} "
                            "(header needs time_s and <dof>_deg for all 14 DOF)")
    idx = [header.index(c) for c in need]
    data = np.empty((len(rows) - 1, len(need)))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) < len(header):
            raise DataFileError(f"capture file {path}: line {r} has {len(row)} fields, "
                                f"header has {len(header)}")
        try:
            data[r - 2] = [float(row[i]) for i in idx]
        except ValueError:
            raise DataFileError(f"capture file {path}: line {r} has a non-numeric value") from None
    bad = np.flatnonzero(~np.all(np.isfinite(data), axis=1))
    if bad.size:
        require_finite(dict(zip(need, data[bad[0]], strict=True)),
                       f"capture file {path}: line {bad[0] + 2}")
    t = data[:, 0]
    return np.radians(data[:, 1:]), _uniform_rate(path, t)


def _uniform_rate(path: Path, t: np.ndarray) -> float:
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise DataFileError(f"capture file {path}: time_s must increase")
    if np.ptp(dt) > 0.01 * np.median(dt):
        raise DataFileError(f"capture file {path}: frames are not evenly spaced (resample first)")
    return float(1.0 / np.median(dt))


# -- BVH -------------------------------------------------------------------------------------

#: Accepted BVH joint names (lower case) for each model joint group.
BVH_JOINTS: dict[str, tuple[str, ...]] = {
    "l_shoulder": ("l_shoulder", "leftshoulder", "left_shoulder", "lhumerus", "leftupperarm",
                   "leftarm"),
    "r_shoulder": ("r_shoulder", "rightshoulder", "right_shoulder", "rhumerus", "rightupperarm",
                   "rightarm"),
    "l_elbow": ("l_elbow", "leftelbow", "left_elbow", "lradius", "leftforearm"),
    "r_elbow": ("r_elbow", "rightelbow", "right_elbow", "rradius", "rightforearm"),
    "l_wrist": ("l_wrist", "leftwrist", "left_wrist", "lhand", "lefthand"),
    "r_wrist": ("r_wrist", "rightwrist", "right_wrist", "rhand", "righthand"),
    "tail": ("tail", "tail_bend", "pygostyle"),
    "tail_fan": ("l_tail", "lefttail", "left_tail", "tail_spread", "tailfan", "tail_fan"),
}


@dataclass
class _BvhJoint:
    name: str
    channels: list[str]
    offset: int  # first column of this joint's channels in a frame row


def read_bvh(path: str | Path) -> tuple[np.ndarray, float]:
    """Angles (n, 14) in rad and the frame rate from a BVH file (see the module doc).

    A small parser: the maintained BVH packages on PyPI either are unmaintained (``bvh``,
    2017) or pull in a 3D math stack (``bvhio``) for what is ~60 lines here.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(f"capture file {path} is unreadable: {exc}") from None
    tokens = text.split()
    if not tokens or tokens[0] != "HIERARCHY":
        raise DataFileError(f"capture file {path}: not a BVH file (no HIERARCHY header)")
    joints: list[_BvhJoint] = []
    ncol = 0
    i = 1
    try:
        while tokens[i] != "MOTION":
            tok = tokens[i]
            if tok in ("ROOT", "JOINT"):
                joints.append(_BvhJoint(tokens[i + 1], [], ncol))
                i += 2
            elif tok == "CHANNELS":
                n = int(tokens[i + 1])
                joints[-1].channels = tokens[i + 2:i + 2 + n]
                joints[-1].offset = ncol
                ncol += n
                i += 2 + n
            elif tok == "OFFSET":
                i += 4
            elif tok == "End":
                i += 2
            else:
                i += 1
        i += 1
        if tokens[i] != "Frames:" or tokens[i + 2:i + 4] != ["Frame", "Time:"]:
            raise DataFileError(f"capture file {path}: BVH MOTION section lacks 'Frames:' and "
                                "'Frame Time:'")
        nframes = int(tokens[i + 1])
        frame_time = float(tokens[i + 4])
        values = np.array(tokens[i + 5:], dtype=float)
    except (IndexError, ValueError):
        raise DataFileError(f"capture file {path}: malformed BVH (truncated or non-numeric "
                            "HIERARCHY/MOTION)") from None
    rows = values.reshape(-1, ncol) if ncol and values.size % ncol == 0 else values
    require_finite({"Frame Time": frame_time, "MOTION": rows}, f"capture file {path}")  # [frame, channel]
    if frame_time <= 0 or nframes < 2:
        raise DataFileError(f"capture file {path}: BVH needs >= 2 frames and a positive frame time")
    if values.size != nframes * ncol:
        raise DataFileError(f"capture file {path}: BVH motion has {values.size} numbers, expected "
                            f"{nframes} frames x {ncol} channels = {nframes * ncol}")
    motion = values.reshape(nframes, ncol)
    by_name = {j.name.lower(): j for j in joints}
    found = {}
    for group, names in BVH_JOINTS.items():
        for n in names:
            if n in by_name:
                found[group] = by_name[n]
                break
        else:
            raise DataFileError(f"capture file {path}: no BVH joint for {group} (accepted names: "
                                f"{', '.join(names)})")
    return _bvh_to_dof(path, found, motion), 1.0 / frame_time


def _rotations(path: Path, joint: _BvhJoint, motion: np.ndarray) -> Rotation:
    rot = [(c[0].upper(), joint.offset + k) for k, c in enumerate(joint.channels)
           if c.lower().endswith("rotation")]
    if not rot:
        raise DataFileError(f"capture file {path}: BVH joint {joint.name} has no rotation channels")
    seq = "".join(a for a, _ in rot)
    return Rotation.from_euler(seq, motion[:, [c for _, c in rot]], degrees=True)  # intrinsic


def _bvh_to_dof(path: Path, found: dict[str, _BvhJoint], motion: np.ndarray) -> np.ndarray:
    out = np.zeros((len(motion), N_DOF))
    col = {n: k for k, n in enumerate(DOF_NAMES)}
    for s, sign in (("l", 1.0), ("r", -1.0)):
        # left axes: flap +x, sweep +z, twist +y; right: -x, -z, +y (mirror symmetric)
        a, b, c = _rotations(path, found[f"{s}_shoulder"], motion).as_euler("XZY").T
        out[:, col[f"{s}_shoulder_flap"]] = sign * a
        out[:, col[f"{s}_shoulder_sweep"]] = sign * b
        out[:, col[f"{s}_shoulder_twist"]] = c
        # elbow: flex about -z (left) / +z (right), twist about +y
        z, y, _ = _rotations(path, found[f"{s}_elbow"], motion).as_euler("ZYX").T
        out[:, col[f"{s}_elbow_flex"]] = -sign * z
        out[:, col[f"{s}_elbow_twist"]] = y
        z, _, _ = _rotations(path, found[f"{s}_wrist"], motion).as_euler("ZYX").T
        out[:, col[f"{s}_wrist_flex"]] = sign * z
    _, y, _ = _rotations(path, found["tail"], motion).as_euler("ZYX").T
    out[:, col["tail_bend"]] = y
    z, _, _ = _rotations(path, found["tail_fan"], motion).as_euler("ZYX").T
    out[:, col["tail_spread"]] = -z  # the left half-fan turns about -z
    return out


def write_bvh(path: str | Path, angles: np.ndarray, rate_hz: float) -> None:
    """Write 14-DOF angles as a BVH in flapsim's convention (for tests and exchange)."""
    col = {n: k for k, n in enumerate(DOF_NAMES)}
    a = np.asarray(angles, float)
    chans: list[np.ndarray] = [np.zeros((len(a), 3))]  # root position
    lines = ["HIERARCHY", "ROOT trunk", "{", "  OFFSET 0 0 0",
             "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    chans.append(np.zeros((len(a), 3)))

    def joint(name: str, order: str, rot: Rotation, depth: int = 1) -> None:
        pad = "  " * depth
        lines.extend([f"{pad}JOINT {name}", f"{pad}{{", f"{pad}  OFFSET 0 0 0",
                      f"{pad}  CHANNELS 3 {' '.join(x + 'rotation' for x in order)}",
                      f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0.01 0", f"{pad}  }}",
                      f"{pad}}}"])
        chans.append(rot.as_euler(order, degrees=True))

    for s, sign in (("l", 1.0), ("r", -1.0)):
        sh = np.stack([sign * a[:, col[f"{s}_shoulder_flap"]], sign * a[:, col[f"{s}_shoulder_sweep"]],
                       a[:, col[f"{s}_shoulder_twist"]]], axis=1)
        joint(f"{s}_shoulder", "XZY", Rotation.from_euler("XZY", sh))
        el = np.stack([-sign * a[:, col[f"{s}_elbow_flex"]], a[:, col[f"{s}_elbow_twist"]]], axis=1)
        joint(f"{s}_elbow", "ZYX", Rotation.from_euler("ZY", el))
        joint(f"{s}_wrist", "ZYX", Rotation.from_euler("Z", sign * a[:, col[f"{s}_wrist_flex"]][:, None]))
    joint("tail", "ZYX", Rotation.from_euler("Y", a[:, col["tail_bend"]][:, None]))
    joint("l_tail", "ZYX", Rotation.from_euler("Z", -a[:, col["tail_spread"]][:, None]))
    lines += ["}", "MOTION", f"Frames: {len(a)}", f"Frame Time: {1.0 / rate_hz:.9f}"]
    data = np.hstack(chans)
    lines += [" ".join(f"{v:.6f}" for v in row) for row in data]
    Path(path).write_text("\n".join(lines) + "\n")


def write_csv(path: str | Path, angles: np.ndarray, rate_hz: float) -> None:
    """Write 14-DOF angles in the flapsim CSV format (degrees)."""
    a = np.degrees(np.asarray(angles, float))
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s"] + [f"{n}_deg" for n in DOF_NAMES])
        for i, row in enumerate(a):
            w.writerow([f"{i / rate_hz:.9f}"] + [f"{v:.6f}" for v in row])
