"""PD muscles: tau = kp (qd - q) + kv (qd' - q') on hinge and ball joints, compiled.

The velocity part ``-kv q'`` is MuJoCo's joint damping (``dof_damping``), which the
``implicitfast`` integrator treats implicitly, so stiff-enough muscles stay stable at
a 4 ms step; this module supplies the rest, ``kp (qd - q) + kv qd'``, as motor
controls (clipped at each motor's torque limit). For a ball joint the position error
is the rotation vector of ``q^-1 qd`` and the velocities are local angular velocities,
the frame MuJoCo uses for ball-joint dofs and their motors.

Targets come from a periodic table over the stroke phase (see
:mod:`flapsim.swim.strokes`): per phase sample, the target joint positions (hinge
angles, ball quaternions) and their phase derivatives (rad per cycle).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: default proportional gains [N m/rad] per joint kind (velocity gains are the joint
#: damping in swimmer.xml). Chosen so that each muscle holds its segment against water
#: drag at stroke speeds within ~0.1-0.2 rad, and dt * sqrt(kp / I) << 2 at 4 ms.
KP = {
    "lumbar": 400.0, "thoracic": 400.0, "neck": 60.0, "shoulder": 220.0, "elbow": 90.0,
    "pronation": 8.0, "wrist": 8.0, "hip": 400.0, "knee": 150.0, "ankle": 30.0,
    "inversion": 10.0,
}


def kind_of(joint_name: str) -> str:
    """The KP key of a swimmer joint name (``elbow_pron_l`` -> ``pronation``)."""
    if joint_name.startswith("elbow_pron"):
        return "pronation"
    if joint_name.startswith("elbow_flex"):
        return "elbow"
    if joint_name.startswith("ankle_inv"):
        return "inversion"
    if joint_name.startswith("ankle_flex"):
        return "ankle"
    return joint_name.rsplit("_", 1)[0] if joint_name.endswith(("_l", "_r")) else joint_name


@njit(cache=True)
def _quat_mul(a0, a1, a2, a3, b0, b1, b2, b3):
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True)
def pd_controls(qpos, jtype, qadr, dadr, act, tq, tv, nsamp, phase, rate, kp, kv, lo, hi,
                ctrl, target_q):
    """Write motor controls for the current phase; also the interpolated target pose.

    ``tq`` (nsamp x nqj, flat) and ``tv`` (nsamp x nvj, flat) are the target tables in
    joint order (hinge: 1 angle, ball: 4 quaternion / 3 angular velocity per cycle);
    ``kp``/``kv`` per joint dof (nvj); ``lo``/``hi`` per motor; ``target_q`` (nqj) gets
    the interpolated target.
    """
    nqj = target_q.size
    nvj = kp.size
    u = (phase - np.floor(phase)) * nsamp
    i0 = int(u)
    if i0 >= nsamp:
        i0 = nsamp - 1
    s = u - i0
    i1 = i0 + 1
    if i1 == nsamp:
        i1 = 0
    for k in range(nqj):
        target_q[k] = tq[i0 * nqj + k] * (1.0 - s) + tq[i1 * nqj + k] * s
    jq = 0
    jv = 0
    for j in range(jtype.size):
        qa = qadr[j]
        da = dadr[j]
        a = act[j]
        if jtype[j] == 0:
            vd = (tv[i0 * nvj + jv] * (1.0 - s) + tv[i1 * nvj + jv] * s) * rate
            tau = kp[jv] * (target_q[jq] - qpos[qa]) + kv[jv] * vd
            ctrl[a] = min(hi[a], max(lo[a], tau))
            jq += 1
            jv += 1
        else:
            # normalised target quaternion (nlerp of the table samples)
            d0 = target_q[jq]
            d1 = target_q[jq + 1]
            d2 = target_q[jq + 2]
            d3 = target_q[jq + 3]
            nd = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3)
            d0 /= nd
            d1 /= nd
            d2 /= nd
            d3 /= nd
            target_q[jq] = d0
            target_q[jq + 1] = d1
            target_q[jq + 2] = d2
            target_q[jq + 3] = d3
            # error rotation e = q^-1 qd, as a rotation vector in the joint's local frame
            e0, e1, e2, e3 = _quat_mul(qpos[qa], -qpos[qa + 1], -qpos[qa + 2], -qpos[qa + 3],
                                       d0, d1, d2, d3)
            if e0 < 0.0:
                e0 = -e0
                e1 = -e1
                e2 = -e2
                e3 = -e3
            sn = np.sqrt(e1 * e1 + e2 * e2 + e3 * e3)
            ang = 2.0 * np.arctan2(sn, e0)
            scale = ang / sn if sn > 1e-12 else 2.0
            for k in range(3):
                ev = (e1, e2, e3)[k] * scale
                vd = (tv[i0 * nvj + jv + k] * (1.0 - s) + tv[i1 * nvj + jv + k] * s) * rate
                tau = kp[jv + k] * ev + kv[jv + k] * vd
                ctrl[a + k] = min(hi[a + k], max(lo[a + k], tau))
            jq += 4
            jv += 3
        _ = da
    return 0
