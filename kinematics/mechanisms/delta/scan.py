"""The fused Delta scan kernel: both IK roots of every limb, the margins of the 8 working modes
(and their union) and the singular fields, per point, compiled with Numba on every core.

It evaluates the same closed forms as `kinematics.mechanisms.delta.closed_form` and
`kinematics.mechanisms.delta.mechanism.limb_margins` (which stay the independent NumPy path; the
tests hold the two equal to rounding), fused per point with no temporaries. Per limb i, with
v = p + (r - R) e_i, x = v.e_i, y = v.t_i, h = v.z, rho = hypot(x, h) and
K = (|v|^2 + l_a^2 - l_b^2) / (2 l_a):

* reach slack min(l_b - near, far - l_b) [m], near = hypot(rho - l_a, y), far = hypot(rho + l_a, y);
* roots theta = atan2(-h, x) +/- atan2(sqrt(rho^2 - K^2), K), wrapped to within pi of the middle
  of the actuator range; actuator slack l_a min(theta - theta_min, theta_max - theta) [m];
* "all" limits: l_b (cone - angle) at the elbow (socket d_i(theta + elbow_socket)) and at the
  platform (socket s_P,i) [m];
* where the limb cannot reach (rho^2 - K^2 below -BOUNDARY_TOL l_b^2), both roots get
  min(reach slack, 0).

Singular fields: per limb (l_b - near)(far - l_b) [m^2] (the sign of rho^2 - K^2: type I where it
changes), per mode det[n_1; n_2; n_3] of that mode's forearm directions (type II), with n = 0
for a limb that cannot reach, as the NumPy path has it.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange

from kinematics.mechanisms.delta.closed_form import DeltaParams
from kinematics.mechanisms.three_limb.closed_form import BOUNDARY_TOL

__all__ = ["DeltaScan", "kernel_geometry", "kernels", "limb_kernel", "scan"]


class DeltaScan(NamedTuple):
    """Per point, modes in the order of `closed_form.MODES`.

    Attributes:
        margin: (N, 8) each working mode's margin [m] (>= 0 inside its workspace).
        det: (N, 8) det[n_1; n_2; n_3] of the mode's unit forearm directions (type II where it
            changes sign).
        disc: (N, 3) per limb (l_b - near)(far - l_b) [m^2] (type I where it changes sign).
    """

    margin: np.ndarray
    det: np.ndarray
    disc: np.ndarray


def kernel_geometry(params: DeltaParams) -> np.ndarray:
    """Everything the kernel needs, packed in one float array (see `_limb`)."""
    P = params
    limbs = np.concatenate([P.e[:, :2], P.t[:, :2], P.platform_sockets], axis=1).ravel()  # 7 per limb
    lo, hi = P.theta_limits
    rest = [P.r - P.R, P.la, P.lb, lo, hi, 0.5 * (lo + hi), P.cone, P.elbow_socket, BOUNDARY_TOL * P.lb**2,
            math.cos(P.elbow_socket), math.sin(P.elbow_socket)]
    return np.concatenate([limbs, rest])


@njit(cache=True)
def _limb(px, py, pz, g, i, passive, out):  # pragma: no cover - compiled
    """Limb i: out[0:2] the slack of roots "+", "-"; out[2:8] their forearm directions (+ then -);
    returns the limb's discriminant field (l_b - near)(far - l_b)."""
    ex, ey, tx, ty = g[7 * i], g[7 * i + 1], g[7 * i + 2], g[7 * i + 3]
    spx, spy, spz = g[7 * i + 4], g[7 * i + 5], g[7 * i + 6]
    off, la, lb, lo, hi, centre, cone, tol = g[21], g[22], g[23], g[24], g[25], g[26], g[27], g[29]
    c_sock, s_sock = g[30], g[31]
    vx = px + off * ex
    vy = py + off * ey
    h = pz
    x = vx * ex + vy * ey
    y = vx * tx + vy * ty
    rho2 = x * x + h * h
    rho = math.sqrt(rho2)
    K = (rho2 + y * y + la * la - lb * lb) / (2.0 * la)
    disc = rho2 - K * K
    near = math.hypot(rho - la, y)
    far = math.hypot(rho + la, y)
    reach = min(lb - near, far - lb)
    if not disc >= -tol:
        out[0] = min(reach, 0.0)
        out[1] = out[0]
        for k in range(2, 8):
            out[k] = 0.0
        return (lb - near) * (far - lb)
    s = math.sqrt(max(disc, 0.0))
    phi0 = math.atan2(-h, x)
    half = math.atan2(s, K)
    two_pi = 2.0 * math.pi
    # cos and sin of the roots phi0 +/- half without trigonometry: x = rho cos(phi0), -h = rho sin(phi0),
    # (K, s) = hypot(K, s) (cos(half), sin(half)) (hypot(K, s) = rho where disc >= 0)
    norm = rho * math.sqrt(K * K + s * s)
    inv = 1.0 / norm if norm > 0.0 else 0.0
    for r in range(2):
        sigma = 1.0 if r == 0 else -1.0
        q = phi0 + sigma * half
        a = q - centre + math.pi
        q = a - two_pi * math.floor(a / two_pi) + centre - math.pi
        if inv > 0.0:
            cq = (K * x + sigma * h * s) * inv
            sq = (sigma * x * s - K * h) * inv
        else:  # on the actuator's axis
            cq = math.cos(q)
            sq = math.sin(q)
        # n = (v - l_a d(q)) / l_b, d(q) = cos q e - sin q z
        nx = (vx - la * cq * ex) / lb
        ny = (vy - la * cq * ey) / lb
        nz = (h + la * sq) / lb
        slack = la * min(q - lo, hi - q)
        if passive:
            # n . d(q + sock), by the angle sum
            ce = (cq * c_sock - sq * s_sock) * (nx * ex + ny * ey) - (sq * c_sock + cq * s_sock) * nz
            cp = -(nx * spx + ny * spy + nz * spz)
            angle = math.acos(min(1.0, max(-1.0, min(ce, cp))))  # the larger angle: acos decreases
            slack = min(slack, lb * (cone - angle))
        m = min(reach, slack)
        out[r] = m if math.isfinite(m) else min(reach, 0.0)
        out[2 + 3 * r] = nx
        out[3 + 3 * r] = ny
        out[4 + 3 * r] = nz
    return (lb - near) * (far - lb)


limb_kernel = _limb
"""One limb's slacks at a point, compiled (`kinematics.mechanisms.delta.exact` tests its columns' gaps with it)."""

_BLOCK = 256
"""Points per work item of the parallel loop (the per-limb scratch arrays are allocated once per block)."""


@njit(cache=True, parallel=True)
def _kernel(x, y, z, g, passive, margin, det, disc):  # pragma: no cover - compiled
    n = x.shape[0]
    for blk in prange((n + _BLOCK - 1) // _BLOCK):
        a = np.empty(8)
        b = np.empty(8)
        c = np.empty(8)
        for k in range(blk * _BLOCK, min(n, (blk + 1) * _BLOCK)):
            disc[k, 0] = _limb(x[k], y[k], z[k], g, 0, passive, a)
            disc[k, 1] = _limb(x[k], y[k], z[k], g, 1, passive, b)
            disc[k, 2] = _limb(x[k], y[k], z[k], g, 2, passive, c)
            for m in range(8):  # the order of MODES: "+++", "++-", ..., "---"; bit (2 - limb) set: root "-"
                ra = (m >> 2) & 1
                rb = (m >> 1) & 1
                rc = m & 1
                margin[k, m] = min(a[ra], b[rb], c[rc])
                ax, ay, az = a[2 + 3 * ra], a[3 + 3 * ra], a[4 + 3 * ra]
                bx, by, bz = b[2 + 3 * rb], b[3 + 3 * rb], b[4 + 3 * rb]
                cx, cy, cz = c[2 + 3 * rc], c[3 + 3 * rc], c[4 + 3 * rc]
                det[k, m] = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)


def scan(params: DeltaParams, points: np.ndarray, passive: bool = True) -> DeltaScan:
    """Evaluate every working mode at platform positions `points` (N, 3) [m] (every limit when
    `passive`, else the actuator range only). Uses every core; the result at a point does not
    depend on what else is in the array."""
    p = np.ascontiguousarray(points, dtype=float)
    n = p.shape[0]
    margin = np.empty((n, 8))
    det = np.empty((n, 8))
    disc = np.empty((n, 3))
    x, y, z = (np.ascontiguousarray(p[:, k]) for k in range(3))
    _kernel(x, y, z, kernel_geometry(params), passive, margin, det, disc)
    return DeltaScan(margin, det, disc)


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (_kernel,)
