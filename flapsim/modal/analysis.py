"""Modal analysis of any MuJoCo model about a rest pose (Kry et al. 2009, section 3.1).

The model is linearised about its rest pose in MuJoCo's joint *velocity* coordinates
(``nv`` of them; ball and free joints live in their 3-/6-dimensional tangent space, so
no quaternion is ever differentiated):

* ``M``: the joint-space mass matrix from ``mj_fullM`` (armature included);
* ``K``: joint stiffness (hinge/slide ``k``, ball ``k I3``, free ``k I6``) plus tendon
  stiffness ``J_t^T k_t J_t``, optionally plus position-servo stiffness of actuators;
* ``G``: velocity-constraint rows ``G qdot = 0``: the active equality constraints'
  Jacobian rows (closed loops) plus any extra constraints the caller names
  (:func:`fix_body_orientation`, :func:`pin_site`, :func:`ground_contact`,
  :func:`fix_joint`, :func:`fix_root`).

The admissible directions are the null space ``N`` of ``G`` (orthonormal, from an SVD,
so redundant rows such as the out-of-plane rows that close a planar loop cost nothing).
The modes solve ``(N^T K N) u = lambda (N^T M N) u`` (``scipy.linalg.eigh``); rigid modes
are the null space of ``N^T K N`` (eigenvalue 0); ``f = sqrt(lambda) / (2 pi)``. The mode
shape in joint coordinates is ``N u`` (the paper's ``R N u``; in joint coordinates
``R`` is the identity). Gravity and contact are ignored, as in the paper: the analysis
describes small vibrations about the rest pose.

Mode numbering is 0-based and counts the rigid modes first, as in the paper's Fig. 3
(for a free-floating creature modes 0-5 are rigid and mode 6 is the first vibration).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np
import scipy.linalg

from flapsim.core.errors import InputError, ModelError

log = logging.getLogger(__name__)

# Relative thresholds (dimensionless). SVD/eigen noise is ~1e-15 of the largest value;
# genuine stiffness or constraint ranges in articulated models span < 1e-6.
CONSTRAINT_RANK_TOL = 1e-9
"""Singular values of ``G`` below this fraction of the largest are redundant rows."""
RIGID_TOL = 1e-9
"""Eigenvalues of ``N^T K N`` below this fraction of the largest are rigid directions."""
MASS_COND_TOL = 1e-12
"""Smallest/largest eigenvalue of ``M`` below this is a singular mass matrix."""
DEGENERATE_TOL = 1e-6
"""Modes whose frequencies differ by less than this fraction are one degenerate cluster."""

_JOINT_KINDS = {
    mujoco.mjtJoint.mjJNT_FREE: "free",
    mujoco.mjtJoint.mjJNT_BALL: "ball",
    mujoco.mjtJoint.mjJNT_SLIDE: "slide",
    mujoco.mjtJoint.mjJNT_HINGE: "hinge",
}
_DOF_COUNT = {"free": 6, "ball": 3, "slide": 1, "hinge": 1}
_DOF_SUFFIX = {
    "free": (":tx", ":ty", ":tz", ":rx", ":ry", ":rz"),
    "ball": (":rx", ":ry", ":rz"),
    "slide": ("",),
    "hinge": ("",),
}


# ---------------------------------------------------------------------------------------
# Extra constraints
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ExtraConstraint:
    """Velocity constraint rows added to the analysis (bilateral, at the rest pose).

    Build them with :func:`fix_body_orientation`, :func:`pin_site`,
    :func:`ground_contact`, :func:`fix_joint` or :func:`fix_root`.
    """

    kind: str
    """'orientation' (body's world angular velocity = 0, 3 rows), 'pin' (site's world
    velocity = 0, 3 rows), 'contact' (each site fixed to the ground: 3 rows, or only the
    vertical row when ``sliding``), 'joint' (the joint's dofs frozen)."""
    names: tuple[str, ...]
    """Body, site or joint names the constraint acts on."""
    sliding: bool = False
    """For 'contact': keep only the normal (z) row, so the feet may slide on the ground."""

    @property
    def label(self) -> str:
        kind = "sliding-contact" if (self.kind == "contact" and self.sliding) else self.kind
        return f"{kind}:{','.join(self.names)}"

    def rows(self, model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
        """The constraint Jacobian rows (k x nv) at the pose held in ``data``."""
        nv = model.nv
        out: list[np.ndarray] = []
        for name in self.names:
            if self.kind == "orientation":
                bid = _lookup(model, mujoco.mjtObj.mjOBJ_BODY, name, "body")
                jacr = np.zeros((3, nv))
                mujoco.mj_jacBody(model, data, None, jacr, bid)
                out.append(jacr)
            elif self.kind in ("pin", "contact"):
                sid = _lookup(model, mujoco.mjtObj.mjOBJ_SITE, name, "site")
                jacp = np.zeros((3, nv))
                mujoco.mj_jacSite(model, data, jacp, None, sid)
                out.append(jacp[2:3] if (self.kind == "contact" and self.sliding) else jacp)
            elif self.kind == "joint":
                jid = _lookup(model, mujoco.mjtObj.mjOBJ_JOINT, name, "joint")
                kind = _JOINT_KINDS[int(model.jnt_type[jid])]
                adr = int(model.jnt_dofadr[jid])
                sel = np.zeros((_DOF_COUNT[kind], nv))
                sel[np.arange(_DOF_COUNT[kind]), adr + np.arange(_DOF_COUNT[kind])] = 1.0
                out.append(sel)
            else:
                raise InputError(f"unknown constraint kind {self.kind!r}")
        return np.vstack(out) if out else np.zeros((0, nv))


def fix_body_orientation(body: str) -> ExtraConstraint:
    """Keep a body's world orientation fixed (e.g. a stabilised head): 3 rows."""
    return ExtraConstraint("orientation", (body,))


def pin_site(site: str) -> ExtraConstraint:
    """Pin a site to the world (e.g. hands on a cart): 3 rows."""
    return ExtraConstraint("pin", (site,))


def ground_contact(sites: Sequence[str] | str, *, sliding: bool = False) -> ExtraConstraint:
    """Feet on the ground as bilateral contact: each site stuck (3 rows), or with
    ``sliding=True`` only held at its height (1 row)."""
    names = (sites,) if isinstance(sites, str) else tuple(sites)
    if not names:
        raise InputError("ground_contact needs at least one site name")
    return ExtraConstraint("contact", names, sliding=sliding)


def fix_joint(joint: str) -> ExtraConstraint:
    """Freeze every dof of one joint."""
    return ExtraConstraint("joint", (joint,))


def root_joints(model: mujoco.MjModel) -> list[int]:
    """The joints that float a root: free joints of bodies attached to the world, and every
    joint of a world-attached body that has a slide joint (a planar root: slide x, slide z,
    hinge y). A hinge alone on a world-attached body is a real joint, not a root."""
    out = []
    for b in range(1, model.nbody):
        if model.body_parentid[b] != 0:
            continue
        joints = [j for j in range(model.njnt) if model.jnt_bodyid[j] == b]
        kinds = {int(model.jnt_type[j]) for j in joints}
        if int(mujoco.mjtJoint.mjJNT_FREE) in kinds or int(mujoco.mjtJoint.mjJNT_SLIDE) in kinds:
            out += joints
    return out


def fix_root(model: mujoco.MjModel) -> list[ExtraConstraint]:
    """Freeze the floating roots (:func:`root_joints`); an :class:`InputError` when the
    model has none (asking to fix nothing is a mistake worth hearing about)."""
    out = [ExtraConstraint("joint", (_joint_name(model, j),)) for j in root_joints(model)]
    if not out:
        raise InputError("the model has no floating root (no free joint, no slide joints on a "
                         "body attached to the world): nothing to fix")
    return out


def parse_constraint(spec: str) -> ExtraConstraint:
    """Parse a CLI constraint: ``orient:BODY``, ``pin:SITE``, ``contact:SITE[,SITE..]``,
    ``sliding-contact:SITE[,SITE..]`` or ``joint:JOINT``."""
    kind, sep, rest = spec.partition(":")
    names = tuple(n.strip() for n in rest.split(",") if n.strip())
    if not sep or not names:
        raise InputError(
            f"constraint {spec!r} is not KIND:NAME; use orient:BODY, pin:SITE, "
            "contact:SITE[,SITE], sliding-contact:SITE[,SITE] or joint:JOINT"
        )
    kind = kind.strip().lower()
    if kind in ("orient", "orientation"):
        if len(names) != 1:
            raise InputError(f"constraint {spec!r}: orient takes one body")
        return fix_body_orientation(names[0])
    if kind == "pin":
        if len(names) != 1:
            raise InputError(f"constraint {spec!r}: pin takes one site")
        return pin_site(names[0])
    if kind == "contact":
        return ground_contact(names)
    if kind == "sliding-contact":
        return ground_contact(names, sliding=True)
    if kind == "joint":
        return ExtraConstraint("joint", names)
    raise InputError(
        f"unknown constraint kind {kind!r} in {spec!r}; "
        "use orient, pin, contact, sliding-contact or joint"
    )


# ---------------------------------------------------------------------------------------
# Result
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class ModalAnalysis:
    """Vibration modes of a model about its rest pose (arrays are read-only views).

    Mode ``i`` is column ``i`` of :attr:`shapes`; modes are sorted by frequency and the
    first :attr:`n_rigid` are rigid (frequency 0).
    """

    rest_qpos: np.ndarray
    """Rest pose (nq,), generalized positions; the linearisation point."""
    eigenvalues: np.ndarray
    """Generalized eigenvalues lambda_i (m,), (rad/s)^2; exactly 0 for rigid modes."""
    freqs_hz: np.ndarray
    """Natural frequencies f_i = sqrt(lambda_i) / (2 pi) (m,), Hz."""
    shapes: np.ndarray
    """Mode shapes N u_i in joint velocity coordinates (nv, m), mass-normalised
    (shapes.T @ M @ shapes = I); rad for rotational dofs, m for translational dofs."""
    modal_vectors: np.ndarray
    """Eigenvectors u_i in the constrained coordinates (m, m)."""
    null_space: np.ndarray
    """Orthonormal basis N (nv, m) of the admissible velocities (G N = 0)."""
    n_rigid: int
    """How many modes are rigid (eigenvalue 0): unconstrained directions without stiffness."""
    mass_matrix: np.ndarray
    """Joint-space mass matrix M (nv, nv) at the rest pose, kg m^2 / kg."""
    stiffness: np.ndarray
    """Joint-space stiffness K (nv, nv), N m/rad or N/m."""
    damping: np.ndarray
    """Joint-space damping C (nv, nv) from dof and tendon damping, N m s/rad or N s/m."""
    constraint_jacobian: np.ndarray
    """All constraint rows G (k, nv) (equality rows first, then the extra constraints)."""
    constraint_rank: int
    """Rank of G: how many dofs the constraints remove."""
    constraint_labels: tuple[str, ...]
    """Which constraints built G (e.g. 'equality:connect#0', 'pin:hand')."""
    dof_labels: tuple[str, ...]
    """One label per dof: joint name plus a component suffix for ball/free joints."""
    dof_joint: np.ndarray
    """Joint id of each dof (nv,)."""
    joint_names: tuple[str, ...]
    """Name of each joint (njnt,); unnamed joints get 'joint#<id>'."""
    joint_kinds: tuple[str, ...]
    """'free', 'ball', 'slide' or 'hinge' for each joint (njnt,)."""
    _cache: dict = field(default_factory=dict, repr=False)

    # -- sizes ---------------------------------------------------------------------------
    @property
    def n_modes(self) -> int:
        """Number of modes (= dimension of the null space)."""
        return int(self.freqs_hz.size)

    @property
    def nv(self) -> int:
        return int(self.shapes.shape[0])

    @property
    def elastic_modes(self) -> range:
        """Indices of the non-rigid modes."""
        return range(self.n_rigid, self.n_modes)

    def _check_mode(self, i: int) -> int:
        if not -self.n_modes <= i < self.n_modes:
            raise InputError(f"mode {i} does not exist; the model has modes 0..{self.n_modes - 1}")
        return i % self.n_modes

    # -- shapes --------------------------------------------------------------------------
    @property
    def internal_dofs(self) -> np.ndarray:
        """Boolean mask (nv,) of dofs that are not part of a free joint."""
        kinds = np.array(self.joint_kinds, dtype=object)[self.dof_joint] if self.nv else []
        return np.asarray([k != "free" for k in kinds], dtype=bool)

    def shape(self, i: int, normalize: str = "max") -> np.ndarray:
        """Mode shape ``i`` (nv,). ``normalize='max'``: largest internal-joint component
        is 1 (so an amplitude multiplies radians of the most-moving joint); ``'mass'``:
        the stored mass-normalised shape."""
        i = self._check_mode(i)
        phi = self.shapes[:, i].copy()
        if normalize == "mass":
            return phi
        if normalize != "max":
            raise InputError(f"normalize must be 'max' or 'mass', not {normalize!r}")
        mask = self.internal_dofs
        scale = np.max(np.abs(phi[mask])) if mask.any() else 0.0
        if scale <= 1e-12 * max(np.max(np.abs(phi)), 1e-300):
            scale = np.max(np.abs(phi))  # a rigid mode of the root only
        return phi / scale

    def joint_participation(self, i: int) -> dict[str, float]:
        """Displacement of each non-free joint in mode ``i`` (max-normalised shape),
        radians (hinge/ball: rotation angle) or metres (slide); largest first."""
        phi = self.shape(i, "max")
        out: dict[str, float] = {}
        for j, name in enumerate(self.joint_names):
            if self.joint_kinds[j] == "free":
                continue
            sel = self.dof_joint == j
            if sel.any():
                out[name] = float(np.linalg.norm(phi[sel]))
        return dict(sorted(out.items(), key=lambda kv: -kv[1]))

    def dominant_joints(self, i: int, count: int = 3, min_share: float = 0.05) -> list[str]:
        """Names of the joints that move most in mode ``i`` (rigid modes: ``['rigid']``)."""
        i = self._check_mode(i)
        if i < self.n_rigid:
            return ["rigid"]
        part = self.joint_participation(i)
        if not part:
            return []
        top = max(part.values())
        return [n for n, v in list(part.items())[:count] if v >= min_share * top]

    def damping_ratios(self) -> np.ndarray:
        """Modal damping ratio zeta_i = phi_i^T C phi_i / (2 omega_i) (m,); NaN for rigid
        modes. Exact when C is a combination of M and K (Rayleigh damping), e.g. uniform
        joint damping over uniform joint stiffness."""
        omega = 2 * np.pi * self.freqs_hz
        c = np.einsum("im,ij,jm->m", self.shapes, self.damping, self.shapes)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = c / (2 * omega)
        z[: self.n_rigid] = np.nan
        return z

    def displaced_qpos(self, model: mujoco.MjModel, i: int, amplitude: float) -> np.ndarray:
        """Rest pose displaced along mode ``i`` (max-normalised shape times ``amplitude``,
        radians of the most-moving joint), through ``mj_integratePos``."""
        return integrate_displacement(model, self.rest_qpos, amplitude * self.shape(i, "max"))

    def modal_coordinates(self, model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
        """Project a pose onto the modes: eta = Phi^T M dq with dq the tangent-space
        difference from the rest pose (m,). Exact inverse of a small displacement."""
        dq = tangent_difference(model, qpos, self.rest_qpos)
        return self.shapes.T @ (self.mass_matrix @ dq)

    # -- reports -------------------------------------------------------------------------
    def table(self, count: int | None = None, *, include_rigid: bool = False) -> list[dict]:
        """One row per mode: index, frequency, damping ratio, dominant joints."""
        zeta = self.damping_ratios()
        idx = range(self.n_modes) if include_rigid else self.elastic_modes
        rows = []
        for i in list(idx)[: count if count is not None else None]:
            rows.append(
                {
                    "mode": i,
                    "rigid": i < self.n_rigid,
                    "freq_hz": float(self.freqs_hz[i]),
                    "damping_ratio": float(zeta[i]) if np.isfinite(zeta[i]) else None,
                    # zeta >= 1: the mode does not oscillate (its frequency is the undamped one)
                    "overdamped": bool(np.isfinite(zeta[i]) and zeta[i] >= 1.0),
                    "dominant_joints": self.dominant_joints(i),
                }
            )
        return rows

    def to_dict(self, *, shapes: bool = False) -> dict:
        """JSON-able summary; every mode's frequency, optionally every shape."""
        out = {
            "nv": self.nv,
            "n_modes": self.n_modes,
            "n_rigid": self.n_rigid,
            "constraint_rank": self.constraint_rank,
            "constraints": list(self.constraint_labels),
            "freqs_hz": [float(f) for f in self.freqs_hz],
            "modes": self.table(include_rigid=True),
            "dof_labels": list(self.dof_labels),
            "rest_qpos": self.rest_qpos.tolist(),
        }
        if shapes:
            out["shapes_max_normalized"] = [
                self.shape(i, "max").tolist() for i in range(self.n_modes)
            ]
        return out


# ---------------------------------------------------------------------------------------
# Tangent-space helpers
# ---------------------------------------------------------------------------------------
def integrate_displacement(
    model: mujoco.MjModel, qpos: np.ndarray, dq: np.ndarray, scale: float = 1.0
) -> np.ndarray:
    """``qpos (+) scale * dq``: apply a tangent-space displacement (nv,) to a pose (nq,)
    with ``mj_integratePos`` (quaternions of ball/free joints stay unit)."""
    q = np.array(qpos, dtype=np.float64, copy=True)
    v = np.asarray(dq, dtype=np.float64)
    if q.shape != (model.nq,) or v.shape != (model.nv,):
        raise InputError(
            f"integrate_displacement needs qpos ({model.nq},) and dq ({model.nv},), "
            f"got {q.shape} and {v.shape}"
        )
    mujoco.mj_integratePos(model, q, np.ascontiguousarray(v), float(scale))
    return q


def tangent_difference(model: mujoco.MjModel, qpos: np.ndarray, qpos_ref: np.ndarray) -> np.ndarray:
    """``qpos (-) qpos_ref``: the tangent-space displacement (nv,) taking ``qpos_ref`` to
    ``qpos`` (``mj_differentiatePos`` with dt = 1)."""
    dq = np.zeros(model.nv)
    mujoco.mj_differentiatePos(
        model, dq, 1.0, np.asarray(qpos_ref, dtype=np.float64), np.asarray(qpos, dtype=np.float64)
    )
    return dq


# ---------------------------------------------------------------------------------------
# The analysis
# ---------------------------------------------------------------------------------------
def rest_pose(
    model: mujoco.MjModel, keyframe: str | int | None = None, qpos: np.ndarray | None = None
) -> np.ndarray:
    """The linearisation pose: ``qpos`` if given, else a keyframe, else ``qpos_spring``."""
    if qpos is not None:
        q = np.array(qpos, dtype=np.float64)
        if q.shape != (model.nq,):
            raise InputError(f"rest qpos has shape {q.shape}; the model needs ({model.nq},)")
    elif keyframe is not None:
        if isinstance(keyframe, str) and not keyframe.lstrip("-").isdigit():
            kid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe)
        else:
            kid = int(keyframe)
            kid = kid if 0 <= kid < model.nkey else -1
        if kid < 0:
            names = [model.key(k).name or str(k) for k in range(model.nkey)]
            raise ModelError(
                f"no keyframe {keyframe!r} in the model; "
                + (f"available: {', '.join(names)}" if names else "it defines no <key>")
            )
        q = np.array(model.key_qpos[kid], dtype=np.float64)
    else:
        q = np.array(model.qpos_spring, dtype=np.float64)
    if not np.all(np.isfinite(q)):
        raise InputError("rest pose contains NaN or infinite values")
    # Normalise quaternions as MuJoCo would (user keyframes are often slightly off).
    mujoco.mj_normalizeQuat(model, q)
    return q


def _joint_name(model: mujoco.MjModel, j: int) -> str:
    return model.joint(j).name or f"joint#{j}"


def _lookup(model: mujoco.MjModel, objtype: int, name: str, what: str) -> int:
    idx = mujoco.mj_name2id(model, objtype, name)
    if idx < 0 and what == "joint" and name.startswith("joint#") and name[6:].isdigit():
        idx = int(name[6:]) if int(name[6:]) < model.njnt else -1  # unnamed joints
    if idx < 0:
        count = {"body": model.nbody, "site": model.nsite, "joint": model.njnt}[what]
        getter = {"body": model.body, "site": model.site, "joint": model.joint}[what]
        names = [getter(k).name for k in range(count) if getter(k).name]
        shown = ", ".join(names[:20]) + (" ..." if len(names) > 20 else "")
        raise ModelError(f"no {what} named {name!r} in the model; {what}s: {shown or 'none named'}")
    return idx


def _sparse_rows(values, rownnz, rowadr, colind, nrow: int, ncol: int) -> np.ndarray:
    dense = np.zeros((nrow, ncol))
    for r in range(nrow):
        a, n = int(rowadr[r]), int(rownnz[r])
        dense[r, colind[a : a + n]] = values[a : a + n]
    return dense


def _tendon_jacobian(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    if model.ntendon == 0:
        return np.zeros((0, model.nv))
    if data.ten_J.size == model.ntendon * model.nv and not hasattr(model, "ten_J_rownnz"):
        return np.array(data.ten_J).reshape(model.ntendon, model.nv)
    return _sparse_rows(
        data.ten_J, model.ten_J_rownnz, model.ten_J_rowadr, model.ten_J_colind,
        model.ntendon, model.nv,
    )


def _actuator_moment(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    if model.nu == 0:
        return np.zeros((0, model.nv))
    return _sparse_rows(
        data.actuator_moment, data.moment_rownnz, data.moment_rowadr, data.moment_colind,
        model.nu, model.nv,
    )


def _equality_rows(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """Equality-constraint Jacobian rows and their violations at the pose in ``data``."""
    nefc = int(data.nefc)
    if nefc == 0:
        return np.zeros((0, model.nv)), np.zeros(0)
    if mujoco.mj_isSparse(model):
        jac = _sparse_rows(
            data.efc_J, data.efc_J_rownnz, data.efc_J_rowadr, data.efc_J_colind, nefc, model.nv
        )
    else:
        jac = np.array(data.efc_J[: nefc * model.nv]).reshape(nefc, model.nv)
    sel = np.asarray(data.efc_type[:nefc]) == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    return jac[sel], np.asarray(data.efc_pos[:nefc])[sel]


def _stiffness(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    joint_kinds: Sequence[str],
    joint_names: Sequence[str],
    override: float | Mapping[str, float] | None,
    scale: float,
    actuators: bool,
) -> np.ndarray:
    nv = model.nv
    k_joint = np.array(model.jnt_stiffness, dtype=np.float64)
    if override is not None:
        if isinstance(override, Mapping):
            unknown = set(override) - set(joint_names)
            if unknown:
                raise ModelError(
                    f"stiffness given for unknown joints {sorted(unknown)}; "
                    f"joints: {', '.join(joint_names[:20])}"
                )
            for j, name in enumerate(joint_names):
                if name in override:
                    k_joint[j] = float(override[name])
        else:
            # A uniform value (the paper's "1 N/rad uniform") covers every internal joint:
            # not the floating root's (free joints, or the slides/hinges of a planar root)
            roots = set(root_joints(model))
            for j, kind in enumerate(joint_kinds):
                if kind != "free" and j not in roots:
                    k_joint[j] = float(override)
    k_joint = k_joint * float(scale)
    if np.any(~np.isfinite(k_joint)) or np.any(k_joint < 0):
        raise InputError("joint stiffness must be finite and non-negative")
    K = np.zeros((nv, nv))
    for j, kind in enumerate(joint_kinds):
        adr = int(model.jnt_dofadr[j])
        n = _DOF_COUNT[kind]
        K[adr : adr + n, adr : adr + n] += k_joint[j] * np.eye(n)
    if model.ntendon:
        jt = _tendon_jacobian(model, data)
        for t in range(model.ntendon):
            kt = float(model.tendon_stiffness[t]) * float(scale)
            if kt == 0.0:
                continue
            lo, hi = model.tendon_lengthspring[t]
            length = float(data.ten_length[t])
            if lo < hi and lo < length < hi:
                # Inside the spring's dead band: no force and, locally, no stiffness.
                log.info("tendon %d rests inside its spring dead band: no stiffness", t)
                continue
            K += kt * np.outer(jt[t], jt[t])
    if actuators and model.nu:
        moment = _actuator_moment(model, data)
        for a in range(model.nu):
            if model.actuator_biastype[a] != mujoco.mjtBias.mjBIAS_AFFINE:
                continue
            # Position servo: force = kp*ctrl - kp*length - kv*velocity (biasprm = 0, -kp, -kv).
            kp = -float(model.actuator_biasprm[a, 1])
            if kp > 0:
                K += kp * np.outer(moment[a], moment[a])
    return 0.5 * (K + K.T)


def _damping(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    C = np.diag(np.array(model.dof_damping, dtype=np.float64))
    if model.ntendon and np.any(model.tendon_damping):
        jt = _tendon_jacobian(model, data)
        C += (jt.T * model.tendon_damping) @ jt
    return C


def _check_mass(M: np.ndarray, dof_labels: Sequence[str]) -> None:
    w, v = np.linalg.eigh(M)
    if w[-1] <= 0 or w[0] <= MASS_COND_TOL * w[-1]:
        weak = np.argsort(-np.abs(v[:, 0]))[:3]
        names = ", ".join(dof_labels[k] for k in weak if abs(v[k, 0]) > 0.1)
        raise ModelError(
            f"the mass matrix is singular (smallest/largest eigenvalue {w[0]:.3g}/{w[-1]:.3g}): "
            f"dofs {names} move (almost) no mass or inertia; give their bodies mass and "
            "inertia, or add armature to those joints"
        )


def _canonicalize(shapes: np.ndarray, U: np.ndarray, freqs: np.ndarray, first: int) -> None:
    """Make eigenvector signs and degenerate-cluster bases reproducible (in place).

    LAPACK returns any orthonormal basis of a repeated eigenvalue's eigenspace and any
    sign; travelling waves built from mode pairs depend on both, so fix them: within a
    cluster, rotate so the shapes restricted to the first independent dofs (index order)
    are lower-triangular with a positive diagonal; a lone mode gets its first
    significant component positive.
    """
    m = shapes.shape[1]
    i = first
    while i < m:
        j = i + 1
        while j < m and abs(freqs[j] - freqs[i]) <= DEGENERATE_TOL * max(freqs[i], 1e-300):
            j += 1
        B = shapes[:, i:j]
        c = j - i
        rows: list[int] = []
        scale = np.max(np.abs(B))
        for r in range(B.shape[0]):
            trial = B[rows + [r], :]
            s = np.linalg.svd(trial, compute_uv=False)
            if s[-1] > 1e-3 * scale:
                rows.append(r)
                if len(rows) == c:
                    break
        if len(rows) == c:
            # B[rows] = L Q^T with Q orthogonal -> B Q is lower triangular on those rows.
            q, r_ = np.linalg.qr(B[rows, :].T)
            signs = np.sign(np.diag(r_))
            signs[signs == 0] = 1.0
            T = q * signs
            shapes[:, i:j] = B @ T
            U[:, i:j] = U[:, i:j] @ T
        j_end = j
        for k in range(i, j_end):
            col = shapes[:, k]
            sig = np.nonzero(np.abs(col) > 1e-3 * np.max(np.abs(col)))[0]
            if sig.size and col[sig[0]] < 0:
                shapes[:, k] *= -1
                U[:, k] *= -1
        i = j_end


def analyze(
    model: mujoco.MjModel,
    *,
    keyframe: str | int | None = None,
    qpos: np.ndarray | None = None,
    constraints: Iterable[ExtraConstraint] = (),
    use_equality: bool = True,
    stiffness: float | Mapping[str, float] | None = None,
    stiffness_scale: float = 1.0,
    actuator_stiffness: bool = False,
) -> ModalAnalysis:
    """Vibration modes of ``model`` about its rest pose.

    Args:
        model: any compiled MuJoCo model.
        keyframe: name or index of a keyframe to use as the rest pose (default: the
            model's ``qpos_spring``, i.e. the joints' ``springref``).
        qpos: an explicit rest pose (nq,), overriding ``keyframe``.
        constraints: extra bilateral constraints (:func:`fix_body_orientation`,
            :func:`pin_site`, :func:`ground_contact`, :func:`fix_joint`, :func:`fix_root`).
        use_equality: include the model's active equality constraints (closed loops).
        stiffness: replace joint stiffness: one value (N m/rad, N/m) for every joint but
            the floating root's (:func:`root_joints`), or a mapping joint name -> value.
        stiffness_scale: multiply all stiffness (joints and tendons) by this.
        actuator_stiffness: add the stiffness of position servos (``kp``) to ``K``.

    Raises:
        ModelError: no stiffness anywhere, a singular mass matrix, constraints removing
            every degree of freedom, or unknown names.
    """
    if model.nv == 0:
        raise ModelError("the model has no degrees of freedom (no joints): nothing to analyse")
    q0 = rest_pose(model, keyframe, qpos)
    data = mujoco.MjData(model)
    data.qpos[:] = q0
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)

    joint_kinds = tuple(_JOINT_KINDS[int(t)] for t in model.jnt_type)
    joint_names = tuple(_joint_name(model, j) for j in range(model.njnt))
    dof_joint = np.array(model.dof_jntid, dtype=np.int64)
    dof_labels = []
    for d in range(model.nv):
        j = int(dof_joint[d])
        dof_labels.append(joint_names[j] + _DOF_SUFFIX[joint_kinds[j]][d - model.jnt_dofadr[j]])
    dof_labels = tuple(dof_labels)

    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    M = 0.5 * (M + M.T)
    _check_mass(M, dof_labels)

    K = _stiffness(
        model, data, joint_kinds, joint_names, stiffness, stiffness_scale, actuator_stiffness
    )
    if not np.any(K):
        raise ModelError(
            "the model has no joint or tendon stiffness (all zero), so it has no vibration "
            "modes: set stiffness= on its joints in the MJCF or pass a uniform stiffness "
            "(stiffness=1.0 / --stiffness 1)"
        )
    C = _damping(model, data)

    rows: list[np.ndarray] = []
    labels: list[str] = []
    if use_equality and model.neq:
        eq_rows, eq_pos = _equality_rows(model, data)
        if eq_rows.shape[0]:
            rows.append(eq_rows)
            labels.append(f"equality:{eq_rows.shape[0]} rows")
            worst = float(np.max(np.abs(eq_pos)))
            if worst > 1e-4:
                log.warning(
                    "the rest pose violates the equality constraints by %.3g (m or rad); "
                    "the modes linearise about an inconsistent pose", worst,
                )
    for c in constraints:
        r = c.rows(model, data)
        rows.append(r)
        labels.append(c.label)
    G = np.vstack(rows) if rows else np.zeros((0, model.nv))

    if G.shape[0]:
        _, s, vt = np.linalg.svd(G, full_matrices=True)
        rank = int(np.sum(s > CONSTRAINT_RANK_TOL * s[0])) if s.size and s[0] > 0 else 0
        N = vt[rank:].T.copy()
    else:
        rank = 0
        N = np.eye(model.nv)
    if N.shape[1] == 0:
        raise ModelError(
            f"the constraints ({', '.join(labels)}) remove every degree of freedom "
            f"(rank {rank} of {model.nv}): drop some constraints"
        )

    Mr = N.T @ M @ N
    Kr = N.T @ K @ N
    Mr = 0.5 * (Mr + Mr.T)
    Kr = 0.5 * (Kr + Kr.T)
    kr_eig = np.linalg.eigvalsh(Kr)
    kmax = max(float(kr_eig[-1]), 0.0)
    n_rigid = int(np.sum(kr_eig <= RIGID_TOL * kmax)) if kmax > 0 else Kr.shape[0]

    lam, U = scipy.linalg.eigh(Kr, Mr)
    order = np.argsort(lam, kind="stable")
    lam, U = lam[order], U[:, order]
    lam = np.where(np.arange(lam.size) < n_rigid, 0.0, np.maximum(lam, 0.0))
    freqs = np.sqrt(lam) / (2 * np.pi)
    shapes = N @ U
    _canonicalize(shapes, U, freqs, n_rigid)
    if n_rigid:
        _canonicalize_rigid(shapes, U, n_rigid)

    def ro(a: np.ndarray) -> np.ndarray:
        a = np.ascontiguousarray(a)
        a.setflags(write=False)
        return a

    log.info(
        "modal analysis: nv=%d, constraint rank %d, %d modes (%d rigid), lowest elastic %s Hz",
        model.nv, rank, lam.size, n_rigid,
        f"{freqs[n_rigid]:.4g}" if lam.size > n_rigid else "none",
    )
    return ModalAnalysis(
        rest_qpos=ro(q0),
        eigenvalues=ro(lam),
        freqs_hz=ro(freqs),
        shapes=ro(shapes),
        modal_vectors=ro(U),
        null_space=ro(N),
        n_rigid=n_rigid,
        mass_matrix=ro(M),
        stiffness=ro(K),
        damping=ro(C),
        constraint_jacobian=ro(G),
        constraint_rank=rank,
        constraint_labels=tuple(labels),
        dof_labels=dof_labels,
        dof_joint=ro(dof_joint),
        joint_names=joint_names,
        joint_kinds=joint_kinds,
    )


def _canonicalize_rigid(shapes: np.ndarray, U: np.ndarray, n_rigid: int) -> None:
    """Rigid modes share eigenvalue 0: give them the same reproducible basis treatment."""
    zeros = np.zeros(n_rigid)
    _canonicalize(shapes[:, :n_rigid], U[:, :n_rigid], zeros, 0)
