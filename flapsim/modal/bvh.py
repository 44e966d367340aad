"""BVH export and import of joint trajectories, so animators can take modal gaits into
their tools (Blender, MotionBuilder, Maya).

Mapping (exact, no fitting): every MuJoCo body of the creature's tree is a BVH joint with
its ``pos`` as OFFSET; every hinge of the body is one rotation channel, in the body's
joint order (MuJoCo composes a body's hinges left to right in the body frame, as BVH
composes channels), the channel angle being the hinge angle in degrees times the sign of
its axis. The floating root gets ``Xposition Yposition Zposition Zrotation Yrotation
Xrotation`` (its quaternion as intrinsic Z-Y-X Euler angles). So a model whose bodies have
no ``quat`` and whose hinges lie along +-x, +-y or +-z body axes (the bundled dog and
human) round-trips exactly; other models are refused with the reason.

Units and axes: lengths are written in ``length_scale`` units per metre (default 100:
centimetres, what most tools assume); axes are MuJoCo's (x forward, y left, **z up**):
in Blender's BVH importer choose "Up: Z", "Forward: X".
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.core.errors import DataFileError, InputError, ModelError
from flapsim.core.io import atomic_path

_AXES = {0: "X", 1: "Y", 2: "Z"}


@dataclass(frozen=True)
class _Channel:
    body: int
    joint: int
    """MuJoCo joint id (-1 for the root's position/rotation channels)."""
    name: str
    """BVH channel name, e.g. 'Xrotation'."""
    sign: float
    """Channel value = sign * hinge angle (deg)."""


def _hinge_axis(model: mujoco.MjModel, j: int) -> tuple[str, float]:
    ax = np.asarray(model.jnt_axis[j], dtype=np.float64)
    k = int(np.argmax(np.abs(ax)))
    if abs(abs(ax[k]) - 1.0) > 1e-9 or np.sum(np.abs(ax)) - abs(ax[k]) > 1e-9:
        raise ModelError(
            f"joint {model.joint(j).name!r} has axis {ax.tolist()}: BVH export needs hinge axes "
            "along +-x, +-y or +-z of the body frame (rotate the body instead of the axis)"
        )
    return _AXES[k] + "rotation", float(np.sign(ax[k]))


def _tree(model: mujoco.MjModel) -> tuple[int, int]:
    """The creature's root body (the world child with a free joint) and that joint."""
    roots = []
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and model.body_parentid[
            model.jnt_bodyid[j]
        ] == 0:
            roots.append((int(model.jnt_bodyid[j]), j))
    if not roots:
        raise ModelError("BVH export needs a floating root (a world body with a free joint)")
    return roots[0]


def _children(model: mujoco.MjModel, b: int) -> list[int]:
    return [c for c in range(1, model.nbody) if model.body_parentid[c] == b and c != b]


class BvhLayout:
    """The hierarchy and channel map of a model's creature tree."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.root, self.root_joint = _tree(model)
        self.channels: list[_Channel] = []
        self.order: list[int] = []
        self._walk(self.root)

    def _walk(self, b: int) -> None:
        m = self.model
        if b != self.root and np.any(np.abs(np.asarray(m.body_quat[b]) - [1, 0, 0, 0]) > 1e-9):
            raise ModelError(
                f"body {m.body(b).name!r} has a quat: BVH offsets cannot rotate a frame; "
                "export needs bodies without quat (put the rotation in the geoms)"
            )
        self.order.append(b)
        if b == self.root:
            for nm in ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation",
                       "Xrotation"):
                self.channels.append(_Channel(b, -1, nm, 1.0))
        else:
            for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]):
                if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
                    raise ModelError(
                        f"joint {m.joint(j).name!r} is not a hinge: BVH export supports hinges "
                        "only below the root (write a ball joint as three hinges)"
                    )
                nm, sign = _hinge_axis(m, j)
                self.channels.append(_Channel(b, j, nm, sign))
        for c in _children(self.model, b):
            self._walk(c)

    def body_channels(self, b: int) -> list[_Channel]:
        return [c for c in self.channels if c.body == b]


def _zyx_from_quat(q: np.ndarray) -> tuple[float, float, float]:
    """Intrinsic Z-Y-X Euler angles (rad) of a unit quaternion: R = Rz(a) Ry(b) Rx(c)."""
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(q, dtype=np.float64))
    R = R.reshape(3, 3)
    b = math.asin(float(np.clip(-R[2, 0], -1.0, 1.0)))
    a = math.atan2(R[1, 0], R[0, 0])
    c = math.atan2(R[2, 1], R[2, 2])
    return a, b, c


def _quat_from_zyx(a: float, b: float, c: float) -> np.ndarray:
    out = np.array([1.0, 0, 0, 0])
    for axis, ang in ((2, a), (1, b), (0, c)):
        ax = np.zeros(3)
        ax[axis] = 1.0
        q = np.zeros(4)
        mujoco.mju_axisAngle2Quat(q, ax, ang)
        res = np.zeros(4)
        mujoco.mju_mulQuat(res, out, q)
        out = res
    return out


def _f(x: float) -> str:
    return f"{x:.6f}"


def write_bvh(
    path: str | os.PathLike,
    model: mujoco.MjModel,
    qpos: np.ndarray,
    frame_time: float,
    *,
    length_scale: float = 100.0,
) -> int:
    """Write the poses ``qpos`` (T, nq) as BVH; returns the number of channels."""
    qpos = np.atleast_2d(np.asarray(qpos, dtype=np.float64))
    if qpos.shape[1] != model.nq or qpos.shape[0] == 0:
        raise InputError(f"qpos must be (T, {model.nq}) with T >= 1, got {qpos.shape}")
    if not (frame_time > 0 and math.isfinite(frame_time)):
        raise InputError("BVH frame time must be a positive number of seconds")
    lay = BvhLayout(model)
    lines = ["HIERARCHY"]

    def emit(b: int, depth: int) -> None:
        ind = "  " * depth
        m = model
        kw = "ROOT" if b == lay.root else "JOINT"
        lines.append(f"{ind}{kw} {m.body(b).name or f'body{b}'}")
        lines.append(f"{ind}{{")
        off = np.zeros(3) if b == lay.root else np.asarray(m.body_pos[b]) * length_scale
        lines.append(f"{ind}  OFFSET {' '.join(_f(v) for v in off)}")
        chans = lay.body_channels(b)
        lines.append(f"{ind}  CHANNELS {len(chans)} {' '.join(c.name for c in chans)}".rstrip())
        kids = _children(model, b)
        for c in kids:
            emit(c, depth + 1)
        if not kids:
            # End Site: the body's first site, else its first geom's centre (a bone tip).
            tip = np.zeros(3)
            sites = np.nonzero(np.asarray(m.site_bodyid) == b)[0]
            if sites.size:
                tip = np.asarray(m.site_pos[sites[0]])
            elif m.body_geomnum[b]:
                tip = np.asarray(m.geom_pos[m.body_geomadr[b]])
            lines.append(f"{ind}  End Site")
            lines.append(f"{ind}  {{")
            lines.append(f"{ind}    OFFSET {' '.join(_f(v) for v in tip * length_scale)}")
            lines.append(f"{ind}  }}")
        lines.append(f"{ind}}}")

    emit(lay.root, 0)
    adr = int(model.jnt_qposadr[lay.root_joint])
    lines += ["MOTION", f"Frames: {qpos.shape[0]}", f"Frame Time: {frame_time:.8f}"]
    for q in qpos:
        a, b, c = _zyx_from_quat(q[adr + 3 : adr + 7])
        vals = []
        for ch in lay.channels:
            if ch.joint < 0:
                if ch.name.endswith("position"):
                    vals.append(q[adr + "XYZ".index(ch.name[0])] * length_scale)
                else:
                    vals.append(math.degrees({"Z": a, "Y": b, "X": c}[ch.name[0]]))
            else:
                vals.append(ch.sign * math.degrees(q[model.jnt_qposadr[ch.joint]]))
        lines.append(" ".join(_f(v) for v in vals))
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return len(lay.channels)


@dataclass(frozen=True)
class BvhData:
    """A parsed BVH file."""

    joints: tuple[str, ...]
    """Joint names in file order."""
    channels: tuple[tuple[str, str], ...]
    """(joint, channel) per motion column."""
    offsets: dict[str, np.ndarray]
    """OFFSET of each joint, file units."""
    frame_time: float
    """Seconds per frame."""
    motion: np.ndarray
    """(T, channels) channel values (degrees, file length units)."""


def read_bvh(path: str | os.PathLike) -> BvhData:
    """Parse a BVH file (hierarchy and motion)."""
    try:
        text = open(path).read()
    except OSError as exc:
        raise DataFileError(f"cannot read BVH file {path}: {exc.strerror}") from None
    tokens = re.split(r"\s+", text.strip())
    joints: list[str] = []
    channels: list[tuple[str, str]] = []
    offsets: dict[str, np.ndarray] = {}
    stack: list[str] = []
    i = 0
    current = None
    try:
        while tokens[i] != "MOTION":
            tok = tokens[i]
            if tok in ("ROOT", "JOINT"):
                current = tokens[i + 1]
                joints.append(current)
                i += 2
            elif tok == "End":
                current = None
                i += 2
            elif tok == "{":
                stack.append(current)
                i += 1
            elif tok == "}":
                stack.pop()
                i += 1
            elif tok == "OFFSET":
                if current is not None:
                    offsets[current] = np.array([float(t) for t in tokens[i + 1 : i + 4]])
                i += 4
            elif tok == "CHANNELS":
                n = int(tokens[i + 1])
                channels += [(current, c) for c in tokens[i + 2 : i + 2 + n]]
                i += 2 + n
            else:
                i += 1
        frames = int(tokens[i + 2])
        frame_time = float(tokens[i + 5])
        vals = np.array([float(t) for t in tokens[i + 6 :]])
    except (IndexError, ValueError) as exc:
        raise DataFileError(f"{path} is not a valid BVH file ({exc})") from None
    if vals.size != frames * len(channels):
        raise DataFileError(
            f"{path}: {vals.size} motion values, expected {frames} frames x {len(channels)} channels"
        )
    return BvhData(tuple(joints), tuple(channels), offsets, frame_time,
                   vals.reshape(frames, len(channels)))


def bvh_to_qpos(
    bvh: BvhData, model: mujoco.MjModel, *, length_scale: float = 100.0
) -> np.ndarray:
    """Map a BVH file written by :func:`write_bvh` back onto ``model``'s qpos (T, nq)."""
    lay = BvhLayout(model)
    want = [(model.body(c.body).name, c.name) for c in lay.channels]
    if list(bvh.channels) != want:
        raise DataFileError("the BVH channels do not match this model's joints (another model?)")
    adr = int(model.jnt_qposadr[lay.root_joint])
    out = np.tile(np.asarray(model.qpos0, dtype=np.float64), (bvh.motion.shape[0], 1))
    for k, row in enumerate(bvh.motion):
        euler = {}
        for ch, v in zip(lay.channels, row, strict=True):
            if ch.joint < 0:
                if ch.name.endswith("position"):
                    out[k, adr + "XYZ".index(ch.name[0])] = v / length_scale
                else:
                    euler[ch.name[0]] = math.radians(v)
            else:
                out[k, model.jnt_qposadr[ch.joint]] = ch.sign * math.radians(v)
        out[k, adr + 3 : adr + 7] = _quat_from_zyx(euler["Z"], euler["Y"], euler["X"])
    return out
