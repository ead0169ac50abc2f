"""A base revolute turning part of a turn: the measure of each circle about its axis.

`partial_turn` decides when a chain is measured so (`Reach` calls it on its setup); `TurnExtent`
is the integrand.

The base turns through [a, b], a range L = b - a in [pi, 2 pi). With W0 the set the rest of the
chain reaches with the base at 0, the reachable set is W = union over theta in [a, b] of
Rot(theta) W0, so on the circle of radius r at height z about the axis (cylindrical (r, phi, z)),
with S = {phi : (r, phi, z) in W0} its arc set, W holds exactly S + [a, b] (a dilation on the
circle). Its length is 2 pi minus the sum of (g - L)+ over the gaps g of S (an angle phi is missed
iff the arc phi - [a, b] of length L lies in a gap); as L >= pi only the largest gap G can exceed
L, so

    |S + [a, b]| = L + c,  c = w - (G - L)+ in [0, w],  w = 2 pi - L,

and |W| = (L / 2 pi) |W_P| + X, X = integral over the profile P of r c(r, z) dr dz, |W_P| the
full turn's solid of revolution (Pappus, measured on the profile P = {(r, z) : S not empty}).
X is integrated by `kinematics.analyses.columns.turned` (columns along z, P's ends bracketed: c
jumps there wherever S is an arc).

`TurnExtent` gives the integrand r c at profile points (r, z):

1. the free turn's search (`Reach.profile_search`): outside P it is 0; inside, its base angle
   theta_0 gives phi_0 = -theta_0, a point of S;
2. the cover test (`Reach.cover`): a search for a point of S between w and pi from phi_0 (the base
   held within pi -/+ (L - pi) of it); where it succeeds the circle is whole: r w (two points of S
   that far apart leave no gap longer than L);
3. otherwise the circle sampled every `step` [m] of arc from phi_0 (the search with the base held
   at 0, the configuration found at phi_0 its first seed, warm starts along the circle): when the
   largest gap between inside samples, at its widest, is <= L the circle is whole; else its two
   ends are bisected to `root_tol` [m] and c = w - (G - L)+, the brackets' widths its error (every
   sample gap that may exceed L is measured: the sum over the gaps holds for any L).

What it can miss (as the engine's sampled columns): a component of S shorter than the step (it
widens a gap), a search miss at a sample (a gap of two steps, far below L). Where W0 has no
volume (the chain after the base has fewer than 3 freedoms for the point), S is a set of
isolated azimuths: sampling finds none of them, only phi_0 and the cover test's far point count
(exact for an arm whose postures lie in a plane through the axis, as the tests' 3R arm). The cover test only
saves work: a circle it fails to prove whole is sampled. The check run repeats the integral with
another search at half the step.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.mechanisms.orientation import ToolOrientation
from kinematics.mechanisms.serial import search as kernels
from kinematics.mechanisms.serial.joint_box import Setup
from kinematics.model.robot import Robot

if TYPE_CHECKING:
    from kinematics.mechanisms.serial.reach import Reach

COVER_SAMPLES = 10_000
"""Profile points of `TurnExtent.uncovered`'s count (main's cover bound, 20 s for the panda)."""

PARTIAL_TURN_MIN = math.pi
"""A first revolute of at least this range [rad] (and less than a full turn) is measured as a
partial turn on the profile (`kinematics.mechanisms.serial.turn`, whose circle measure holds for
any range; the cover test that saves its work needs L >= pi); below it, in 3-D."""

OUTSIDE, PARTIAL, WHOLE = 0, 1, 2
"""The integrand's signature: outside P, an arc of the circle, the whole circle (the quadrature
bounds its error by the variation where the signature changes among an interval's nodes)."""


class TurnExtent:
    """The integrand r c(r, z) of a partial base turn's volume (module docstring)."""

    def __init__(self, reach: Reach) -> None:
        assert reach.turn is not None
        self.reach = reach
        self.range = float(reach.turn[1] - reach.turn[0])
        self.w = 2 * math.pi - self.range

    def margin(self, points: np.ndarray) -> np.ndarray:
        """(N,) the free turn's margins [m] at profile points (N, 2) (`Reach.profile_margin`): >= 0 on P."""
        return self.reach.profile_margin(points)[:, 0]

    def for_check(self) -> TurnExtent:
        """The same integrand through the check run's search (`Reach.checker`)."""
        return TurnExtent(self.reach.checker)

    def uncovered(self, samples: int = COVER_SAMPLES) -> tuple[float, float]:
        """D [m^3], the measure (weight 2 pi r) of the profile where the cover test fails, and its
        standard error, by `samples` profile points uniform in the box [0, R] x [-R, R] (seeded,
        sorted so that neighbours come in turn: warm starts). Every circle of P lies in W for an
        arc of at least L and wholly where the test succeeds, so with k = w / 4 pi,
        (L / 2 pi) V_P + X lies within k D of V_P - k D (`kinematics.analyses.columns.turned`)."""
        reach = self.reach
        R = reach.setup.reach
        rng = np.random.default_rng(reach.seed)
        pts = np.column_stack([R * np.sqrt(rng.random(samples)), rng.uniform(-R, R, samples)])
        pts = pts[np.lexsort((pts[:, 1], np.round(pts[:, 0], 2)))]
        m, q = reach.profile_search(pts)
        f = float(((m >= 0) & (reach.cover(pts, m, q) < 0)).mean())
        box = 2 * math.pi * R ** 3  # the weighted measure of the sampled box
        return box * f, box * math.sqrt(max(f * (1 - f), 1.0 / samples) / samples)

    def __call__(self, points: np.ndarray, step: float, root_tol: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """At profile points (N, 2) = (r, z) [m]: the integrand r c (N,) [m rad], its error
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
        if self.range >= math.pi:  # (the cover test needs L >= pi)
            cover = reach.cover(pts[inside], m[inside], q[inside])
            spent += len(inside)
        else:
            cover = np.full(len(inside), -1.0)
        whole = inside[cover >= 0]
        value[whole], sig[whole] = pts[whole, 0] * w, WHOLE
        arc = inside[cover < 0]
        if len(arc):
            e, de, full, n = self._circle(pts[arc], q[arc], step, root_tol)
            spent += n
            r = pts[arc, 0]
            value[arc], error[arc] = r * e, r * de
            sig[arc] = np.where(full, WHOLE, PARTIAL)
        return value, error, sig, spent

    def _circle(self, pts: np.ndarray, q: np.ndarray, step: float, root_tol: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """c (M,) [rad] on the circles through profile points (M, 2) whose free turn's
        solutions are q (M, n), from S sampled round each circle from phi_0: w minus the excesses
        over L of the gaps between inside samples that may exceed L even at their widest, their
        ends bisected; their errors (M,) [rad]; whether the circle is whole (M,); the searches spent."""
        w, L = self.w, self.range
        M = len(pts)
        r, z = pts[:, 0], pts[:, 1]
        n = np.maximum(8, np.ceil(2 * math.pi * r / step)).astype(np.int64)  # a sample every step of arc
        start = np.concatenate([[0], np.cumsum(n)[:-1]])
        row = np.repeat(np.arange(M), n)
        j = np.arange(int(n.sum())) - np.repeat(start, n)
        h = 2 * math.pi / n  # [rad]
        phi0 = -q[:, 0]
        seed = q.copy()
        seed[:, 0] = 0.0  # the free turn's configuration with the base at 0 reaches phi_0's point
        m = self._w0_margin(r[row], phi0[row] + j * h[row], z[row], seed[row])
        ins = (m >= 0) | (j == 0)  # phi_0 itself is in S (reached by the seed)
        spent = len(m)
        # the gaps between consecutive inside samples (round the circle), in samples
        idx = np.flatnonzero(ins)
        nxt = np.concatenate([idx[1:], [0]])
        same = np.concatenate([row[idx[1:]] == row[idx[:-1]], [False]])
        first = idx[np.searchsorted(row[idx], row[idx], side="left")]  # each row's first inside (j = 0)
        gap = np.where(same, nxt - idx, n[row[idx]] - (idx - first))
        value, err = np.full(M, w), np.zeros(M)
        wide = np.flatnonzero(gap * h[row[idx]] > L)  # the gaps that may exceed L even at their widest
        if len(wide):
            t = row[idx[wide]]
            a0 = phi0[t] + (idx[wide] - start[t]) * h[t]  # a gap's first end: inside, then outside at + h
            a1 = a0 + gap[wide] * h[t]  # its last end: inside, then outside at - h
            lo_b, n1 = self._bisect(r[t], z[t], a0, h[t], seed[t], root_tol)
            hi_b, n2 = self._bisect(r[t], z[t], a1, -h[t], seed[t], root_tol)
            spent += n1 + n2
            G = (hi_b[0] + hi_b[1]) / 2 - (lo_b[0] + lo_b[1]) / 2
            value -= np.bincount(t, np.maximum(G - L, 0.0), minlength=M)
            err += np.bincount(t, np.abs(lo_b[1] - lo_b[0]) + np.abs(hi_b[1] - hi_b[0]), minlength=M)
        return value, err, value >= w, spent

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


def partial_turn(robot: Robot, kin: Any, s: Setup, orientation: ToolOrientation | None
                 ) -> tuple[Setup, tuple[float, float] | None]:
    """A spatial setup whose first chain joint is a revolute moving the point through a range
    L in [pi, 2 pi) (and leaving a fixed orientation unchanged): the revolved setup and the range
    (lo, hi); otherwise (s, None). The reachable set W is then the turns by [lo, hi] of the set W0
    the rest of the chain reaches: on each circle about the axis, A + [lo, hi] with A the
    azimuths of W0 there, which is the whole circle as soon as A holds two azimuths at least
    2 pi - L apart, and at least an arc of length L wherever A is not empty."""
    from kinematics.generic.batched import PRISMATIC
    from kinematics.mechanisms.serial.joint_box import dof_of

    if (s.mode != "spatial" or kin.kind[0] == PRISMATIC or not len(s.active) or bool(s.periodic[0])
            or int(s.active[0]) != dof_of(robot, int(kin.idx_v[0]))):
        return s, None
    lo, hi = float(s.lo[0]), float(s.hi[0])
    direction = kin.rotation[0] @ kin.axis[0]
    if hi - lo < PARTIAL_TURN_MIN or (orientation is not None and not orientation.invariant_about(direction)):
        return s, None
    if orientation is None and rest_rank(robot, kin, s) < 3:
        return s, None  # W0 has no volume: its circles' azimuths are isolated, which sampling cannot find
    return dataclasses.replace(s, mode="revolved", active=s.active[1:], lo=s.lo[1:], hi=s.hi[1:],
                               periodic=s.periodic[1:], axis_origin=kin.translation[0].copy(),
                               axis_direction=direction), (lo, hi)


def rest_rank(robot: Robot, kin: Any, s: Setup, probes: int = 32) -> int:
    """The largest rank of the position Jacobian over the moving joints after the first at `probes`
    seeded configurations of the joint box: below 3 the set W0 they reach has no volume."""
    from kinematics.mechanisms.serial.joint_box import dof_of

    chain = [dof_of(robot, int(v)) for v in kin.idx_v]
    rest = [k for k, d in enumerate(chain) if d in set(s.active[1:].tolist())]
    if len(rest) < 3:
        return len(rest)
    rng = np.random.default_rng(0)
    Q = np.tile(s.base[chain].astype(float), (probes, 1))
    pos = {int(d): i for i, d in enumerate(s.active)}
    for k in rest:
        i = pos[chain[k]]
        Q[:, k] = s.lo[i] + (s.hi[i] - s.lo[i]) * rng.random(probes)
    J = kernels.chain_jacobian_many(np.ascontiguousarray(Q), kin.kind, kin.axis, kin.rotation, kin.translation,
                                    kin.frame_translation)[:, :, rest]
    sv = np.linalg.svd(J, compute_uv=False)
    return int((sv > np.maximum(1e-9 * sv[:, :1], 1e-12)).sum(axis=1).max())
