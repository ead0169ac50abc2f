"""A base revolute turning part of a turn: the measure of each circle about its axis.

The base turns through [a, b], a range L = b - a in [pi, 2 pi). With W0 the set the rest of the
chain reaches with the base at 0, the reachable set is W = union over theta in [a, b] of
Rot(theta) W0, so on the circle of radius r at height z about the axis (cylindrical (r, phi, z)),
with S = {phi : (r, phi, z) in W0} its arc set, W holds exactly S + [a, b] (a dilation on the
circle). Its length is 2 pi minus the sum of (g - L)+ over the gaps g of S (an angle phi is missed
iff the arc phi - [a, b] of length L lies in a gap). As L >= pi, only the gap through the
antipode of a point phi_0 in S can exceed L, so

    |S + [a, b]| = L + min(w, E),  w = 2 pi - L,

E the angular extent of S seen from phi_0 (the arc from its first to its last point, going
through phi_0) when S has no point at an angular distance in [w, pi] from phi_0, and then
min(w, E) = w when it has one (S + [a, b] is the whole circle: two points of S between w and pi
apart leave no gap longer than L). Neither depends on which phi_0 of S is used. So

    |W| = (L / 2 pi) |W_P| + X,   X = integral over the profile P of r min(w, E(r, z)) dr dz,

|W_P| the full turn's solid of revolution (Pappus, measured on the profile P = {(r, z) : S not
empty}) and X an integral whose integrand falls to 0 at the boundary of P (S shrinks to a point
there), integrated by the same adaptive quadrature (`kinematics.analyses.columns.turned`).

`TurnExtent` gives the integrand at profile points (r, z):

1. the free turn's search (`Reach.profile_search`): outside P the integrand is 0; inside, its base
   angle theta_0 gives phi_0 = -theta_0, a point of S;
2. the cover test (`Reach.cover`): a search of the far arc (distance w .. pi from phi_0) with the
   base held within pi -/+ (L - pi) of it; where it succeeds the circle is whole: r w;
3. otherwise the near arc phi_0 +- w sampled every `step` [m] of arc (the search with the base
   held at 0, the configuration found at phi_0 its first seed, warm starts along the arc), the
   outermost sign change on each side bracketed by bisection to `root_tol` [m]: r min(w, E),
   the brackets' widths (times r: arc lengths) its error; an inside sample at either end of the
   arc makes E >= w.

What it can miss (as the engine's sampled columns): a component of S shorter than the step
beyond the outermost one found on the near arc, and a far-arc point the cover search does not
reach (the check run repeats both with another search and half the step).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from kinematics.mechanisms.serial.reach import Reach

MIN_ARC_SAMPLES = 4
"""Near-arc samples on each side of phi_0 at least, whatever the step."""

OUTSIDE, PARTIAL, WHOLE = 0, 1, 2
"""The integrand's signature: outside P, an arc of the circle, the whole circle (the quadrature
bounds its error by the variation where the signature changes among an interval's nodes)."""


class TurnExtent:
    """The integrand r min(w, E(r, z)) of a partial base turn's volume (module docstring)."""

    def __init__(self, reach: Reach) -> None:
        assert reach.turn is not None
        self.reach = reach
        self.range = float(reach.turn[1] - reach.turn[0])
        self.w = 2 * math.pi - self.range

    def for_check(self) -> TurnExtent:
        """The same integrand through the check run's search (`Reach.checker`)."""
        return TurnExtent(self.reach.checker)

    def __call__(self, points: np.ndarray, step: float, root_tol: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """At profile points (N, 2) = (r, z) [m]: the integrand r min(w, E) (N,) [m rad], its error
        (N,) from the root brackets, the signature (N,) (OUTSIDE, PARTIAL, WHOLE) and the number
        of searches spent."""
        reach, w = self.reach, self.w
        pts = np.ascontiguousarray(points, dtype=float)
        N = len(pts)
        value, error = np.zeros(N), np.zeros(N)
        sig = np.full(N, OUTSIDE, np.int64)
        m, q = reach.profile_search(pts)
        spent = N
        inside = np.flatnonzero(m >= 0)
        if not len(inside):
            return value, error, sig, spent
        cover = reach.cover(pts[inside], m[inside], q[inside])
        spent += len(inside)
        whole = inside[cover >= 0]
        value[whole], sig[whole] = pts[whole, 0] * w, WHOLE
        arc = inside[cover < 0]
        if len(arc):
            e, de, full, n = self._near_arc(pts[arc], q[arc], step, root_tol)
            spent += n
            r = pts[arc, 0]
            value[arc] = r * np.minimum(w, e)
            error[arc] = np.where(full, 0.0, r * de)
            sig[arc] = np.where(full | (e >= w), WHOLE, PARTIAL)
        return value, error, sig, spent

    def _near_arc(self, pts: np.ndarray, q: np.ndarray, step: float, root_tol: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """Extents E (M,) [rad] of S on the near arcs phi_0 +- w at profile points (M, 2) whose free
        turn's solutions are q (M, n), their errors (M,) [rad], whether an arc's end is inside
        (M,) (then E >= w), and the searches spent."""
        w = self.w
        M = len(pts)
        r, z = pts[:, 0], pts[:, 1]
        k = np.maximum(MIN_ARC_SAMPLES, np.ceil(w * r / step)).astype(np.int64)  # samples a side: every step of arc
        n = 2 * k + 1
        start = np.concatenate([[0], np.cumsum(n)[:-1]])
        row = np.repeat(np.arange(M), n)
        j = np.arange(int(n.sum())) - np.repeat(start, n) - k[row]  # -k .. k about phi_0
        h = w / k  # the arc's sample spacing [rad]
        phi0 = -q[:, 0]
        seed = q.copy()
        seed[:, 0] = 0.0  # the free turn's configuration with the base at 0 reaches phi_0's point
        m = self._w0_margin(r[row], phi0[row] + j * h[row], z[row], seed[row])
        ins = (m >= 0) | (j == 0)  # phi_0 itself is in S (reached by the seed)
        spent = len(m)
        hi_j = np.maximum.reduceat(np.where(ins, j, -1), start)  # the outermost inside samples
        lo_j = np.minimum.reduceat(np.where(ins, j, 1), start)
        full = (hi_j == k) | (lo_j == -k)
        E = np.full(M, w)
        dE = np.zeros(M)
        todo = np.flatnonzero(~full)
        if len(todo):
            t = todo
            a_hi, n1 = self._bisect(r[t], z[t], phi0[t] + hi_j[t] * h[t], h[t], seed[t], root_tol)
            a_lo, n2 = self._bisect(r[t], z[t], phi0[t] + lo_j[t] * h[t], -h[t], seed[t], root_tol)
            spent += n1 + n2
            E[t] = (a_hi[0] + a_hi[1]) / 2 - (a_lo[0] + a_lo[1]) / 2
            dE[t] = np.abs(a_hi[1] - a_hi[0]) + np.abs(a_lo[1] - a_lo[0])
        return E, dE, full, spent

    def _w0_margin(self, r: np.ndarray, phi: np.ndarray, z: np.ndarray, seeds: np.ndarray) -> np.ndarray:
        """The margins (size of r) of W0 (the base held at 0) at cylindrical points (r, phi, z)."""
        reach = self.reach
        rr, pp, zz = r.ravel(), phi.ravel(), z.ravel()
        world = reach.origin + (rr * np.cos(pp))[:, None] * reach.basis[0] + \
            (rr * np.sin(pp))[:, None] * reach.basis[1] + zz[:, None] * reach.basis[2]
        return reach.distance(world, (reach.lo_base0, reach.hi_base0), first_seed=seeds)[0]

    def _bisect(self, r: np.ndarray, z: np.ndarray, inside: np.ndarray, h: np.ndarray, seed: np.ndarray,
                root_tol: float) -> tuple[tuple[np.ndarray, np.ndarray], int]:
        """The bracket (inside end, outside end) [rad] of the sign change of W0's margin between
        the inside azimuths `inside` (M,) and inside + h (M,) (outside), narrowed by bisection until
        r |bracket| <= root_tol; and the searches spent."""
        a, b = inside.copy(), inside + h
        spent = 0
        while True:
            act = np.flatnonzero(r * np.abs(b - a) > root_tol)
            if not len(act):
                return (a, b), spent
            mid = 0.5 * (a[act] + b[act])
            m = self._w0_margin(r[act], mid, z[act], seed[act])
            spent += len(act)
            ok = m >= 0
            a[act] = np.where(ok, mid, a[act])
            b[act] = np.where(ok, b[act], mid)
