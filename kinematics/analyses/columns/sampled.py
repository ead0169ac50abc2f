"""Sampled columns: a margin's sign changes along columns, each bracketed to a root tolerance
(see the package docstring)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from kinematics.errors import InvalidInputError

ROOT_TOL = 1e-12
"""Width [m] to which every column root is bracketed."""

CHUNK_POINTS = 1 << 19
"""Margin evaluations per batch (bounds memory to ~ this many x targets doubles)."""

SECANT_TRIES = 8
"""A jump bracket's secant probes taken even where the bracket did not halve (`_refine`), before
a stalled bracket is bisected again."""


class Counter:
    """Columns and margin evaluations spent, and the inside points' extent, over a measurement."""

    def __init__(self, d: int) -> None:
        self.columns = 0
        self.points = 0
        self.lo = np.full(d, np.inf)
        self.hi = np.full(d, -np.inf)


def check_margin(values: np.ndarray, n: int) -> np.ndarray:
    """A margin's output as (n, T) floats; raises `InvalidInputError` on a wrong row count or NaN/inf."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 1:
        values = values[:, None]
    if values.shape[0] != n:
        raise InvalidInputError("margin", f"returned {values.shape[0]} rows for {n} points")
    if not np.all(np.isfinite(values)):
        raise InvalidInputError("margin", "returned NaN or inf")
    return values


def column_lengths(
    margin: Callable[[np.ndarray], np.ndarray],
    base: np.ndarray,
    z0: float,
    z1: float,
    step: float,
    axis: int = -1,
    counter: Counter | None = None,
    root_tol: float = ROOT_TOL,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inside length of each column per target, the bound on its root-bracket error, and its
    number of interval ends (its topology; an end on the box's face counts too).

    Args:
        margin: (N, d) points [m] -> (N, T) or (N,) margins, >= 0 inside.
        base: (M, d - 1) the columns' other coordinates [m].
        z0: the column's start along `axis` [m].
        z1: the column's end along `axis` [m].
        step: sampling step [m].
        root_tol: width [m] to which every root is bracketed.

    Returns:
        (M, T) lengths [m], (M, T) sums of the final bracket widths [m], (M, T) interval ends.
    """
    base = np.asarray(base, dtype=float)
    M, e = base.shape
    d = e + 1
    ax = axis % d
    others = [k for k in range(d) if k != ax]
    n = max(1, math.ceil((z1 - z0) / step - 1e-9))
    h = (z1 - z0) / n
    zs = z0 + h * np.arange(n + 1)
    zs[-1] = z1
    per = max(1, CHUNK_POINTS // (n + 1))
    out_len: list[np.ndarray] = []
    out_err: list[np.ndarray] = []
    out_cross: list[np.ndarray] = []
    for c0 in range(0, M, per):
        b = base[c0:c0 + per]
        m = len(b)
        pts = np.empty((m, n + 1, d))
        pts[:, :, others] = b[:, None, :]
        pts[:, :, ax] = zs[None, :]
        vals = check_margin(margin(pts.reshape(-1, d)), m * (n + 1)).reshape(m, n + 1, -1)
        T = vals.shape[2]
        inside = vals >= 0.0
        length = (inside[:, :-1] & inside[:, 1:]).sum(axis=1) * h
        err = np.zeros((m, T))
        change = inside[:, :-1] != inside[:, 1:]
        out_cross.append(change.sum(axis=1) + inside[:, 0] + inside[:, -1])
        c, k, t = np.nonzero(change)
        if counter is not None:
            counter.points += m * (n + 1)
            last = inside[:, :, -1]
            if last.any():
                ii = np.nonzero(last)
                p_in = pts[ii]
                counter.lo = np.minimum(counter.lo, p_in.min(axis=0))
                counter.hi = np.maximum(counter.hi, p_in.max(axis=0))
        if len(c):
            root, width, evals = _refine(margin, b[c], zs[k], zs[k + 1], vals[c, k, t], vals[c, k + 1, t], t, others, ax,
                                         tol=root_tol, group=c * n + k)
            if counter is not None:
                counter.points += evals
            left_in = inside[c, k, t]
            part = np.where(left_in, root - zs[k], zs[k + 1] - root)
            np.add.at(length, (c, t), part)
            np.add.at(err, (c, t), width)
        out_len.append(length)
        out_err.append(err)
    if counter is not None:
        counter.columns += M
    return np.concatenate(out_len), np.concatenate(out_err), np.concatenate(out_cross)


def _refine(margin: Callable[[np.ndarray], np.ndarray], base: np.ndarray, a: np.ndarray, b: np.ndarray,
            fa: np.ndarray, fb: np.ndarray, target: np.ndarray, others: list[int], ax: int,
            max_iter: int = 200, tol: float = ROOT_TOL, group: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, int]:
    """Roots of target columns of the margin in the brackets [a, b] (f(a), f(b) of opposite signs).

    Illinois false position; a point closer than the tolerance to an end is nudged to the
    tolerance (Brent), and a bracket that did not halve in two steps is bisected, so every bracket
    ends narrower than `tol`. A bracket that stalls (from the second step on: the first false
    position step of a jump barely moves its outside end) is taken for a jump of the margin (a
    closed loop's falls from its slack inside to minus a small least-squares residual outside,
    which goes to zero at the reach boundary): from then on the secant through the last two
    outside points (f < 0) estimates the root, and the point evaluated is that estimate moved
    0.45 tol towards the bracket's farther end (two such steps close the bracket once the
    estimate is within tol / 2: on a residual linear in the distance, the first estimate). A
    probe that lands outside adds an outside point, so the next estimate is better though the
    bracket barely shrank: the first SECANT_TRIES probes are taken whether or not the bracket
    halved; after them a stalled bracket is bisected, as is every step before two outside points
    are known (at most SECANT_TRIES evaluations beyond bisection's count). On the Gepetto
    five-bar: 11.3 evaluations a bracket with the secant after a second stall and never on a
    stalled bracket, 7.8 this way.

    Brackets of several targets in one interval of one column (the same `group`) share their
    evaluations while they coincide: each step, brackets with the same group and the same ends
    are probed at the first one's point (the lowest target's), which lies inside each of them, and
    each moves by its own target's sign there. Targets that share a root (a union and the branch
    that bounds it, the branches of one reach) are refined for the price of one; where their signs
    at a probe differ, their brackets part and go on separately. Every bracket still ends narrower
    than `tol` around a sign change of its own target.
    Returns (root, final bracket width, margin evaluations).
    """
    lo, hi = a.copy(), b.copy()
    flo, fhi = fa.copy(), fb.copy()
    side = np.zeros(len(lo), np.int8)  # which end moved last: -1 lo, +1 hi (Illinois halving)
    width_two_ago = hi - lo
    width_prev = hi - lo
    stalls = np.zeros(len(lo), np.int8)
    secants = np.zeros(len(lo), np.int64)
    # the last two outside points and their raw margins (Illinois halves flo / fhi), the newest last
    neg = fa < 0
    ox1, of1 = np.where(neg, a, b), np.where(neg, fa, fb)
    ox0, of0 = np.full(len(lo), np.nan), np.full(len(lo), np.nan)
    d = len(others) + 1
    evals = 0
    for it in range(max_iter):
        active = np.flatnonzero(hi - lo > tol)
        if len(active) == 0:
            break
        L, H, FL, FH = lo[active], hi[active], flo[active], fhi[active]
        W = H - L
        x = L - FL * W / (FH - FL)
        x = np.where(np.isfinite(x), x, 0.5 * (L + H))
        stalled = 0.5 * width_two_ago[active] < W
        if it >= 1:
            stalls[active] += stalled
            jump = stalls[active] >= 1
            x1, f1, x0, f0 = ox1[active], of1[active], ox0[active], of0[active]
            with np.errstate(divide="ignore", invalid="ignore"):
                est = x1 - f1 * (x1 - x0) / (f1 - f0)
            probe = est + np.where(H - est > est - L, 0.45, -0.45) * tol  # towards the farther end
            use = jump & (~stalled | (secants[active] < SECANT_TRIES)) & np.isfinite(probe) & (probe > L) & (probe < H)
            secants[active] += use
            x = np.where(use, probe, np.where(stalled | jump, 0.5 * (L + H), x))
        nudge = 0.45 * tol
        x = np.where(x - L < nudge, L + nudge, x)
        x = np.where(H - x < nudge, H - nudge, x)
        lead, inv = _leaders(None if group is None else group[active], L, H)
        x = x[lead][inv]
        pts = np.empty((len(lead), d))
        pts[:, others] = base[active[lead]]
        pts[:, ax] = x[lead]
        vals = check_margin(margin(pts), len(lead))
        evals += len(lead)
        fx = vals[inv, target[active]]
        out = fx < 0
        ox0[active] = np.where(out, ox1[active], ox0[active])
        of0[active] = np.where(out, of1[active], of0[active])
        ox1[active] = np.where(out, x, ox1[active])
        of1[active] = np.where(out, fx, of1[active])
        same_lo = (fx >= 0) == (FL >= 0)
        # Illinois: when the same end moves twice in a row, halve the other end's value
        s = side[active]
        halve_hi = same_lo & (s == -1)
        halve_lo = ~same_lo & (s == 1)
        FH = np.where(halve_hi, 0.5 * FH, FH)
        FL = np.where(halve_lo, 0.5 * FL, FL)
        L = np.where(same_lo, x, L)
        FL = np.where(same_lo, fx, FL)
        H = np.where(same_lo, H, x)
        FH = np.where(same_lo, FH, fx)
        width_two_ago[active] = width_prev[active]
        width_prev[active] = H - L
        lo[active], hi[active], flo[active], fhi[active] = L, H, FL, FH
        side[active] = np.where(same_lo, -1, 1)
    return 0.5 * (lo + hi), hi - lo, evals



def _leaders(group: np.ndarray | None, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Brackets that coincide (the same group and ends): (the first index of each distinct one,
    each bracket's position in that list), so that bracket i is probed at leader lead[inv[i]]."""
    if group is None:
        idx = np.arange(len(lo))
        return idx, idx
    _, lead, inv = np.unique(np.stack([group.astype(float), lo, hi], axis=1), axis=0, return_index=True,
                             return_inverse=True)
    return lead, np.ravel(inv)
