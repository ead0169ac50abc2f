"""A working mode's volume from exact vertical extents: an independent reference for the
adaptive volume estimator.

Along the vertical line through (x, y), every constraint of limb i in root s is a sign condition
on a polynomial of degree <= 2 in z. With v = p + (d - b) e_i, A = v.w_i (linear in z) and
f(c) = |v - c w_i|^2 - L^2 (quadratic in z, the rod equation at actuator value c),
the roots are q = A -/+ sqrt(D), D = A^2 - f(0), and (for a stroke [lo, hi]):

* reach: D >= 0;
* root "-": q >= lo  <=>  A >= lo and f(lo) >= 0;   q <= hi  <=>  A <= hi or f(hi) <= 0;
* root "+": q <= hi  <=>  A <= hi and f(hi) >= 0;   q >= lo  <=>  A >= lo or f(lo) <= 0;
* theta read as the rod-rail angle: n.w = (A - q)/L = +/-sqrt(D)/L, so a bound on it is D <= or
  >= L^2 cos^2 of the limit (with the sign of the root);
* phi (tangential): n.t = p.t/L does not depend on z: the line is wholly in or out.

So the set of admissible z is a union of intervals whose ends are roots of those polynomials:
sort all of them, test each gap's midpoint, and add the lengths of the gaps that pass. That is
exact up to rounding. The area integral of that length over (x, y) is done by nested adaptive
Gauss-Kronrod quadrature (scipy.integrate.quad), whose error estimate bounds the result.

Only modes of the "rod-rail" theta convention (or the strokes alone) are supported: under the
elevation convention the theta bound is not polynomial in z.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.mechanisms.p2us.closed_form import MODES, P2USParams, mode_index, rod_rail_bounds
from kinematics.mechanisms.p2us.scan import bounding_box, check_limits


class ColumnVolume(NamedTuple):
    """volume [m^3], the quadrature's error estimate [m^3], integrand evaluations."""

    volume: float
    error: float
    evaluations: int


def _roots(a: float, b: float, c: float) -> list[float]:
    """Real roots of a z^2 + b z + c."""
    if a == 0.0:
        return [] if b == 0.0 else [-c / b]
    disc = b * b - 4 * a * c
    if disc < 0:
        return []
    s = math.sqrt(disc)
    q = -0.5 * (b + math.copysign(s, b))
    return [q / a, c / q] if q != 0.0 else [0.0]


class _Limb:
    """Coefficients of limb i's polynomials in z for a given (x, y)."""

    def __init__(self, P: P2USParams, i: int, root: int, passive: bool) -> None:
        self.ex, self.ey = P.e[i, 0], P.e[i, 1]
        self.tx, self.ty = P.t[i, 0], P.t[i, 1]
        self.wx, self.wy, self.wz = P.w[i]
        self.off, self.L, (self.lo, self.hi) = P.d - P.b, P.L, P.stroke
        self.minus = root == 1
        self.passive = passive
        _, c_lo, c_hi = rod_rail_bounds(P)
        # cos(theta) = n.w = +sqrt(D)/L for "-", -sqrt(D)/L for "+", and c_hi <= n.w <= c_lo:
        # bounds on D (None: cannot bind; d_max < 0: can never hold)
        self.d_max: float | None = None
        self.d_min: float | None = None
        self.s_lo, self.s_hi = math.sin(P.phi_limits[0]), math.sin(P.phi_limits[1])
        if passive and self.minus:
            if c_lo < 1.0:
                self.d_max = (P.L * c_lo) ** 2 if c_lo >= 0.0 else -1.0
            if c_hi > 0.0:
                self.d_min = (P.L * c_hi) ** 2
        elif passive:
            if c_lo < 0.0:
                self.d_min = (P.L * c_lo) ** 2
            if c_hi > -1.0:
                self.d_max = (P.L * c_hi) ** 2 if c_hi <= 0.0 else -1.0

    def setup(self, x: float, y: float) -> tuple[list[float], bool]:
        """Breakpoints in z and whether the (z-independent) phi bound holds."""
        a = x + self.off * self.ex
        c = y + self.off * self.ey
        self.a, self.c = a, c
        # A = a0 + wz z;  f(k) = z^2 - 2 k wz z + (a^2 + c^2 - L^2 - 2 k (a wx + c wy) + k^2)
        self.a0 = a * self.wx + c * self.wy
        r2 = a * a + c * c - self.L ** 2
        self.r2 = r2
        pts: list[float] = []
        # D = A^2 - f(0) = (wz^2 - 1) z^2 + 2 a0 wz z + a0^2 - r2
        k2 = self.wz ** 2 - 1.0
        pts += _roots(k2, 2 * self.a0 * self.wz, self.a0 ** 2 - r2)
        for k in (self.lo, self.hi):
            pts += _roots(1.0, -2 * k * self.wz, r2 - 2 * k * self.a0 + k * k)
            pts.append((k - self.a0) / self.wz)
        for bound in (self.d_max, self.d_min):
            if bound is not None and bound >= 0:
                pts += _roots(k2, 2 * self.a0 * self.wz, self.a0 ** 2 - r2 - bound)
        phi_ok = True
        if self.passive:
            sphi = -(x * self.tx + y * self.ty) / self.L
            phi_ok = self.s_lo <= sphi <= self.s_hi
        return pts, phi_ok

    def ok(self, z: np.ndarray) -> np.ndarray:
        A = self.a0 + self.wz * z
        f0 = z * z + self.r2
        D = A * A - f0

        def f(k: float) -> np.ndarray:
            return f0 - 2 * k * A + k * k

        good = D >= 0
        if self.minus:
            good &= (self.lo <= A) & (f(self.lo) >= 0) & ((self.hi >= A) | (f(self.hi) <= 0))
        else:
            good &= (self.hi >= A) & (f(self.hi) >= 0) & ((self.lo <= A) | (f(self.lo) <= 0))
        if self.d_max is not None:
            good &= self.d_max >= D
        if self.d_min is not None:
            good &= self.d_min <= D
        return good


def _column_length(limbs: list[_Limb], x: float, y: float) -> float:
    pts: list[float] = []
    for limb in limbs:
        p, phi_ok = limb.setup(x, y)
        if not phi_ok:
            return 0.0
        pts += p
    if len(pts) < 2:
        return 0.0
    z = np.unique(np.array(pts))
    mid = 0.5 * (z[1:] + z[:-1])
    good = np.ones(len(mid), bool)
    for limb in limbs:
        good &= limb.ok(mid)
    return float(np.sum((z[1:] - z[:-1])[good]))


def column_length(P: P2USParams, mode: str = "---", limits: str = "actuators") -> Callable[[float, float], float]:
    """(x, y) [m] -> length [m] of the z-set where working mode `mode` assembles within `limits`."""
    passive = check_limits(limits)
    if passive and P.theta_convention != "rod-rail":
        raise InvalidInputError("limits", "exact columns need the rod-rail theta convention (or --limits actuators)")
    roots = [0 if c == "+" else 1 for c in MODES[mode_index(mode)]]
    limbs = [_Limb(P, i, roots[i], passive) for i in range(3)]
    return lambda x, y: _column_length(limbs, x, y)


def mode_volume(P: P2USParams, mode: str = "---", limits: str = "actuators", *, epsrel: float = 1e-9,
                limit: int = 400) -> ColumnVolume:
    """Volume [m^3] of working mode `mode` by exact z-extents and nested adaptive quadrature.

    Slow (pure Python, ~10^6 integrand calls: minutes): a reference for tests and docs, not a tool.
    The error is quad's outer estimate plus the largest inner one times the x range.
    """
    from scipy import integrate

    length = column_length(P, mode, limits)
    lo, hi = bounding_box(P)
    count = [0]
    inner_err = [0.0]

    def g(y: float, x: float) -> float:
        count[0] += 1
        return length(x, y)

    def h(x: float) -> float:
        val, err = integrate.quad(g, lo[1], hi[1], args=(x,), epsabs=0.0, epsrel=epsrel, limit=limit)
        inner_err[0] = max(inner_err[0], err)
        return val

    vol, err = integrate.quad(h, lo[0], hi[0], epsabs=0.0, epsrel=epsrel, limit=limit)
    return ColumnVolume(vol, float(err + inner_err[0] * (hi[0] - lo[0])), count[0])
