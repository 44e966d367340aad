"""Body wrenches -> generalized forces, compiled: qfrc += J^T w for every body at once.

Force providers accumulate, per body ``b``, a wrench about the *world origin*:
``w[b, 0:3] += p x f + tau`` and ``w[b, 3:6] += f`` for a force ``f`` at world point
``p`` (plus any pure torque ``tau``). Expressing every wrench about one fixed point
makes wrenches additive across bodies, so the whole tree maps in O(nbody + nv):

1. sum each body's wrench into its parent (children have larger ids in MuJoCo), so
   ``W[b]`` is the total wrench on the subtree rooted at ``b``;
2. for each dof ``j`` of body ``b``, with motion axis ``cdof[j] = (omega, v_c)``
   given at ``c = subtree_com[body_rootid[b]]``, the generalized force is
   ``omega . W_tau + (v_c - omega x c) . W_f`` (the axis moved to the origin).

This equals ``mj_applyFT`` summed over bodies (tested to 1e-12) without a Python loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, fastmath=False)
def add_force(w, b, fx, fy, fz, px, py, pz):
    """Accumulate force ``f`` applied at world point ``p`` on body ``b`` into flat ``w``."""
    o = 6 * b
    w[o + 0] += py * fz - pz * fy
    w[o + 1] += pz * fx - px * fz
    w[o + 2] += px * fy - py * fx
    w[o + 3] += fx
    w[o + 4] += fy
    w[o + 5] += fz


@njit(cache=True)
def map_wrenches(w, nbody, nv, body_parentid, body_rootid, dof_bodyid, cdof, subtree_com, qfrc):
    """Add J^T w to ``qfrc`` (length nv). ``w`` (flat nbody*6) is consumed (subtree sums).

    Returns 0, or 1 when a wrench is not finite (then nothing is added).
    """
    for k in range(6 * nbody):
        if not np.isfinite(w[k]):
            return 1
    for b in range(nbody - 1, 0, -1):
        p = body_parentid[b]
        if p > 0:
            for k in range(6):
                w[6 * p + k] += w[6 * b + k]
    for j in range(nv):
        b = dof_bodyid[j]
        r = body_rootid[b]
        cx = subtree_com[3 * r]
        cy = subtree_com[3 * r + 1]
        cz = subtree_com[3 * r + 2]
        ox = cdof[6 * j]
        oy = cdof[6 * j + 1]
        oz = cdof[6 * j + 2]
        # linear part of the axis moved from c to the origin: v_c - omega x c
        vx = cdof[6 * j + 3] - (oy * cz - oz * cy)
        vy = cdof[6 * j + 4] - (oz * cx - ox * cz)
        vz = cdof[6 * j + 5] - (ox * cy - oy * cx)
        o = 6 * b
        qfrc[j] += (
            ox * w[o] + oy * w[o + 1] + oz * w[o + 2] + vx * w[o + 3] + vy * w[o + 4] + vz * w[o + 5]
        )
    return 0


@njit(cache=True, inline="always")
def body_vector(xmat, b, lx, ly, lz):
    """Body-frame vector (lx, ly, lz) of body ``b`` in world coordinates (flat xmat)."""
    m = 9 * b
    return (xmat[m] * lx + xmat[m + 1] * ly + xmat[m + 2] * lz,
            xmat[m + 3] * lx + xmat[m + 4] * ly + xmat[m + 5] * lz,
            xmat[m + 6] * lx + xmat[m + 7] * ly + xmat[m + 8] * lz)


@njit(cache=True, inline="always")
def body_point(xpos, xmat, b, lx, ly, lz):
    """Body-frame point (lx, ly, lz) of body ``b`` in world coordinates (flat arrays)."""
    vx, vy, vz = body_vector(xmat, b, lx, ly, lz)
    return xpos[3 * b] + vx, xpos[3 * b + 1] + vy, xpos[3 * b + 2] + vz
