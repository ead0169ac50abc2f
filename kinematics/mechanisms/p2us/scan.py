"""The fused 3-[P2(US)] scan kernel: IK in all 8 working modes, every limit and both singularity
measures at once, compiled with Numba and run on every core.

It evaluates the same closed forms as `kinematics.mechanisms.p2us.closed_form` (the tests hold the two equal to
rounding) but fuses them per point, with no trigonometry and no temporaries, which is what makes
scans of 10^7 points per second possible on two cores.

Margins. For working mode m the *margin* is the smallest slack of every constraint of every limb,
in metres, positive inside that mode's workspace:

* reach: (A^2 - G) / 2L (the IK discriminant over 2L; the two roots merge at 0, a type I pose);
* stroke: q - q_min and q_max - q;
* theta, "elevation" convention: L x the cross product of the rod's elevation vector with each
  end of the allowed arc (the trig-free test of `parallel.passive_limits_ok`), ~ the rod tip's
  distance from the limit; "rod-rail" convention: L (n.w - cos theta_max) and L (cos theta_min - n.w);
* phi: L (sin phi - sin phi_min) and L (sin phi_max - sin phi).

The margin is continuous in the platform position, so its zero set, the workspace boundary, can
be interpolated linearly between samples (`kinematics.analyses.cells`).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange

from kinematics.mechanisms.p2us.closed_form import MODES, P2USParams, angle_bounds, rod_rail_bounds
from kinematics.mechanisms.three_limb.modes import LIMITS as LIMITS
from kinematics.mechanisms.three_limb.modes import check_limits as check_limits

PAPER_VOLUME_M3 = 0.13397
"""Paper B, Sec. 8: the workspace volume with the limits of eq. 30 [m^3]."""


class ScanResult(NamedTuple):
    """Per point and mode, modes in the order of `parallel.MODES`.

    Attributes:
        margin: (N, 8) constraint margin [m] (>= 0: inside that mode's workspace).
        det: (N, 8) det[n_1; n_2; n_3] (signed; type II where it vanishes; |det| = iota_II).
        disc: (N, 3) per-limb IK discriminant [m^2] (type I where it vanishes;
            iota_I = sqrt(min disc)/L, the same for both roots of a limb).
    """

    margin: np.ndarray
    det: np.ndarray
    disc: np.ndarray


def kernel_geometry(params: P2USParams) -> np.ndarray:
    """Everything the kernel needs, packed in one float array (see `_kernel`)."""
    d_lo, d_hi, narrow, s_lo, s_hi = angle_bounds(params)
    limbs = np.concatenate([params.e[:, :2], params.w], axis=1).ravel()  # ex ey wx wy wz per limb
    rod_rail, c_lo, c_hi = rod_rail_bounds(params)
    rest = [params.L, params.d - params.b, *params.stroke, *d_lo, *d_hi, float(narrow), s_lo, s_hi,
            float(rod_rail), c_lo, c_hi]
    return np.concatenate([limbs, rest])


@njit(cache=True)
def limb_kernel(px, py, pz, g, i, passive):  # pragma: no cover - compiled
    """(slack, nx, ny, nz) of roots "+" and "-" of limb i, and the discriminant."""
    ex, ey, wx, wy, wz = g[5 * i], g[5 * i + 1], g[5 * i + 2], g[5 * i + 3], g[5 * i + 4]
    L, off, q_lo, q_hi = g[15], g[16], g[17], g[18]
    vx = px + off * ex
    vy = py + off * ey
    A = vx * wx + vy * wy + pz * wz
    disc = A * A - (vx * vx + vy * vy + pz * pz) + L * L
    root = math.sqrt(disc) if disc > 0.0 else 0.0
    reach = disc * (0.5 / L)
    plus = _root(A + root, vx, vy, pz, ex, ey, wx, wy, wz, L, reach, q_lo, q_hi, g, passive)
    minus = _root(A - root, vx, vy, pz, ex, ey, wx, wy, wz, L, reach, q_lo, q_hi, g, passive)
    return plus, minus, disc


@njit(cache=True)
def _root(q, vx, vy, pz, ex, ey, wx, wy, wz, L, reach, q_lo, q_hi, g, passive):  # pragma: no cover
    nx = (vx - q * wx) / L
    ny = (vy - q * wy) / L
    nz = (pz - q * wz) / L
    slack = min(reach, q - q_lo, q_hi - q)
    if passive:
        ce = -(nx * ex + ny * ey)  # cos(phi) cos(eps): along the inward horizontal
        se = -nz  # cos(phi) sin(eps): downward
        after_lo = g[19] * se - g[20] * ce
        before_hi = ce * g[22] - se * g[21]
        arc = min(after_lo, before_hi) if g[23] > 0.5 else max(after_lo, before_hi)
        if g[26] > 0.5:  # theta = angle between rod and rail: cos theta = n . w
            nw = nx * wx + ny * wy + nz * wz
            arc = min(nw - g[28], g[27] - nw)
        sphi = nx * ey - ny * ex  # -n . t_i = sin(phi)
        slack = min(slack, L * min(arc, sphi - g[24], g[25] - sphi))
    return slack, nx, ny, nz


@njit(cache=True)
def _mode(a, b, c, margin, det, k, m):  # pragma: no cover - compiled
    margin[k, m] = min(a[0], b[0], c[0])
    det[k, m] = a[1] * (b[2] * c[3] - b[3] * c[2]) + a[2] * (b[3] * c[1] - b[1] * c[3]) \
        + a[3] * (b[1] * c[2] - b[2] * c[1])


@njit(cache=True, parallel=True)
def _kernel(x, y, z, g, passive, margin, det, disc):  # pragma: no cover - compiled
    for k in prange(x.shape[0]):
        p0, m0, disc[k, 0] = limb_kernel(x[k], y[k], z[k], g, 0, passive)
        p1, m1, disc[k, 1] = limb_kernel(x[k], y[k], z[k], g, 1, passive)
        p2, m2, disc[k, 2] = limb_kernel(x[k], y[k], z[k], g, 2, passive)
        # the order of parallel.MODES: "+++", "++-", "+-+", "+--", "-++", ...
        _mode(p0, p1, p2, margin, det, k, 0)
        _mode(p0, p1, m2, margin, det, k, 1)
        _mode(p0, m1, p2, margin, det, k, 2)
        _mode(p0, m1, m2, margin, det, k, 3)
        _mode(m0, p1, p2, margin, det, k, 4)
        _mode(m0, p1, m2, margin, det, k, 5)
        _mode(m0, m1, p2, margin, det, k, 6)
        _mode(m0, m1, m2, margin, det, k, 7)


def scan(params: P2USParams, points: np.ndarray, limits: str = "all") -> ScanResult:
    """Evaluate every working mode at platform positions `points` (N, 3) [m].

    Uses every core (Numba threads); call it on chunks of a grid to bound memory. The result at a
    point does not depend on what else is in the array.
    """
    passive = check_limits(limits)
    p = np.ascontiguousarray(points, dtype=float)
    n = p.shape[0]
    margin = np.empty((n, len(MODES)))
    det = np.empty((n, len(MODES)))
    disc = np.empty((n, 3))
    x, y, z = (np.ascontiguousarray(p[:, k]) for k in range(3))
    _kernel(x, y, z, kernel_geometry(params), passive, margin, det, disc)
    return ScanResult(margin, det, disc)


def bounding_box(params: P2USParams) -> tuple[np.ndarray, np.ndarray]:
    """A box containing every reachable platform position [m].

    Limb i reaches p only if p + d e_i lies within L of its rail segment
    {A_i + q w_i : q in stroke}; intersect the three limbs' boxes.
    """
    lo = np.full(3, -np.inf)
    hi = np.full(3, np.inf)
    for i in range(3):
        ends = np.array([params.base_points[i] + q * params.w[i] for q in params.stroke]) - params.d * params.e[i]
        lo = np.maximum(lo, ends.min(axis=0) - params.L)
        hi = np.minimum(hi, ends.max(axis=0) + params.L)
    return lo, hi


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (_kernel,)
