"""Volume (or area) of {x : f(x) >= 0} by column integration: exact columns, adaptive quadrature.

The region is given by a continuous *margin* f (positive inside, in metres) over a box that
contains it. One axis (the shortest side by default) is the *column axis*; a column's inside
length l is integrated over the other axes. Two paths:

**Exact columns** (3D margins with an `exact_columns` attribute, such as the 3-[P2(US)]'s, see
`kinematics.mechanisms.p2us.exact`): every column's intervals come exactly from roots of quadratics, with a
*signature* that changes wherever l is not smooth (another constraint takes over an end, an
interval appears or vanishes, a face parallel to the axis). Slice areas A(x) = integral of
l(x, y) dy by `piecewise_1d`: nodes every `step` (at least MIN_NODES), breaks located by
bisection on the signature, each smooth piece integrated by adaptive Gauss-Legendre rules after
the grading y = u + (v - u)(3t^2 - 2t^3), which makes square-root edges analytic. The volume
V = integral of A(x) dx by `adaptive_1d`. Nothing along a column can be missed; a feature
narrower than the node spacing in both quadrature directions can.

**Sampled columns** (any other margin): the margin every `step` along the column, every sign
change bracketed and refined (Illinois false position with a bisection safeguard and Brent's
tolerance nudge; bisection from a bracket's second stall on, where the margin jumps, as a
closed loop's does at the reach boundary) to a bracket narrower than `root_tol` (default
`ROOT_TOL` = 1e-12 m; the brackets' widths are part of the error estimate); nested `adaptive_1d`.

`adaptive_1d`: a Gauss-Legendre rule on every interval and on its two halves, the halves' sum
as its value and |whole - halves| as its error estimate, plus the variation bound
width x (max - min of the values) wherever the signature changes among its nodes (there l has
kinks, jumps or square-root edges, where the two rules can agree by accident). On smooth pieces
the difference is dominated by the whole interval's error, so the sum over the accepted
intervals is a conservative estimate; it is not a rigorous bound. Intervals are halved largest
estimate first until the sum meets rtol; the slices' own estimates (<= rtol / 4) are carried
into the outer integral.

**What the method can miss** (stated, not estimated):

* sampled columns only: along a column, an inside interval or an outside gap shorter than
  `step` can fall between two samples (the 3-[P2(US)] margin has no Lipschitz bound to skip
  ahead safely: its stroke and joint-angle terms go through sqrt(discriminant)). Near a surface
  grazing the columns this biases the volume low: 1.6e-4 relative on the 3-[P2(US)] at 5 mm;
* across columns, a feature between the nodes of every interval at every level is not seen.
  `check` reruns the whole computation at half the step (twice the nodes); where the two disagree
  beyond their error estimates, or the last target's difference exceeds its tolerance, it halves
  the step again, up to CHECK_HALVINGS times in all, and compares the last two runs (a sliver thinner than the step shrinks with it: between two
  boundaries tangent to each other, the part a column can miss has an area of order step^1.5).
  The result is the finest run's, its error at least the last two runs' difference; it reports
  not converged if even those disagree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.sizes import MAX_POINTS

ROOT_TOL = 1e-12
"""Width [m] to which every column root is bracketed."""

MIN_NODES = 16
"""Exact columns: fewest starting nodes per quadrature direction (32 in the check run), whatever the
step: a step wider than the box would otherwise start both runs from the same few nodes."""

CHECK_HALVINGS = 3
"""`check`: the most times the step is halved (s/2, s/4, s/8) while successive runs disagree (or the
last target's difference exceeds its tolerance)."""

RTOL_FLOOR = 1e-9
"""Tightest relative tolerance accepted: 1000 x the root brackets over a metre-sized box, so
neither the brackets nor double-precision sums of ~1e6 columns (~1e-10) dominate the estimate."""

BREAK_WIDTH = 1e-3
"""`piecewise_1d`: a located break's bracket is at most this fraction of the node spacing (or
narrower than xtol). Under the pieces' grading a bracket of relative width w spans ~sqrt(w / 3) of
the rule's variable at the piece's end, so a wider one puts the first levels' Gauss nodes across
the break, whose variation bound then refines there level by level; bisecting a break 10 more
times (one column each) measured 1.8-2.6x fewer columns in all on p2us and the Delta, and a
smaller error estimate."""

OUTER_SPAN = 6
"""Exact columns: the volume's outer integral starts from intervals of this many node spacings;
the 12 slices of each (the whole interval's 4-node rule and its halves') then leave no gap wider
than ~0.99 node spacing, the inner direction's (4 spacings: 0.66, at 1.5x the slices)."""

CHUNK_POINTS = 1 << 19
"""Margin evaluations per batch (bounds memory to ~ this many x targets doubles)."""


@dataclass(frozen=True)
class ColumnVolume:
    """Measure of {f_t >= 0} per target t (volume [m^3] in 3D, area [m^2] in 2D).

    Attributes:
        estimate: (T,) the measure.
        error: (T,) estimated absolute error: the quadrature's sum of |parent - children| over
            the accepted cells plus the root brackets' widths integrated (not a bound: components
            thinner than `step` along a column are not in it; see the module docstring).
        converged: every target's error estimate is <= its tolerance (rtol x its measure, or
            x floor x the last target's), the last target is
            not empty (an empty result cannot be told from sampling past everything), and, with
            check, the two runs agree within their estimates.
        step: sampling step along the columns [m]; cell: starting quadrature interval [m].
        columns: columns measured; points_evaluated: margin evaluations.
        check_difference: (T,) |this run - the check run| (NaN without check).
        box: (2, d) [min, max] of the inside points found for the last target (NaN if none).
        target_converged: (T,) per target: its error estimate is within its tolerance and, with
            check, the two runs agree on it within their estimates (`converged` also needs the
            budget to last and the last target to be non-empty).
        check_agrees: (T,) per target: the two runs agree within their estimates (True without check).
        root_tol: sampled columns: the width [m] every root was bracketed to.
    """

    estimate: np.ndarray
    error: np.ndarray
    converged: bool
    rtol: float
    step: float
    cell: float
    columns: int
    points_evaluated: int
    check_difference: np.ndarray
    box: np.ndarray
    target_converged: np.ndarray
    check_agrees: np.ndarray
    root_tol: float = ROOT_TOL


def _within(estimate: np.ndarray, error: np.ndarray, rtol: float, floor: float) -> np.ndarray:
    """(T,) each target's error within its tolerance: rtol x its measure, or x floor x the last's."""
    tol = np.maximum(rtol * np.abs(estimate), rtol * floor * abs(float(estimate[-1])))
    return np.asarray(error <= tol * (1.0 + 1e-12))


class _Counter:
    def __init__(self, d: int) -> None:
        self.columns = 0
        self.points = 0
        self.lo = np.full(d, np.inf)
        self.hi = np.full(d, -np.inf)


def _check_margin(values: np.ndarray, n: int) -> np.ndarray:
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
    counter: _Counter | None = None,
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
        vals = _check_margin(margin(pts.reshape(-1, d)), m * (n + 1)).reshape(m, n + 1, -1)
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
                                         tol=root_tol)
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
            max_iter: int = 200, tol: float = ROOT_TOL) -> tuple[np.ndarray, np.ndarray, int]:
    """Roots of target columns of the margin in the brackets [a, b] (f(a), f(b) of opposite signs).

    Illinois false position; a point closer than the tolerance to an end is nudged to the
    tolerance (Brent), and a bracket that did not halve in two steps is bisected, so every bracket
    ends narrower than `tol`. A bracket that stalls a second time is taken for a jump of the margin
    (a closed loop's falls from its slack inside to minus a small least-squares residual outside,
    which goes to zero at the reach boundary): from then on the secant through the last two
    outside points (f < 0) estimates the root, and the point evaluated is that estimate moved
    0.45 tol towards the bracket's farther end (two such steps close the bracket once the
    estimate is within tol / 2: on a residual linear in the distance, the first estimate); a step
    that lands nowhere useful (the bracket did not halve in two steps) is a bisection, as is every
    step before two outside points are known.
    Returns (root, final bracket width, margin evaluations).
    """
    lo, hi = a.copy(), b.copy()
    flo, fhi = fa.copy(), fb.copy()
    side = np.zeros(len(lo), np.int8)  # which end moved last: -1 lo, +1 hi (Illinois halving)
    width_two_ago = hi - lo
    width_prev = hi - lo
    stalls = np.zeros(len(lo), np.int8)
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
        if it >= 2:
            stalls[active] += stalled
            jump = stalls[active] >= 2
            x1, f1, x0, f0 = ox1[active], of1[active], ox0[active], of0[active]
            with np.errstate(divide="ignore", invalid="ignore"):
                est = x1 - f1 * (x1 - x0) / (f1 - f0)
            probe = est + np.where(H - est > est - L, 0.45, -0.45) * tol  # towards the farther end
            use = jump & ~stalled & np.isfinite(probe) & (probe > L) & (probe < H)
            x = np.where(use, probe, np.where(stalled | jump, 0.5 * (L + H), x))
        nudge = 0.45 * tol
        x = np.where(x - L < nudge, L + nudge, x)
        x = np.where(H - x < nudge, H - nudge, x)
        pts = np.empty((len(active), d))
        pts[:, others] = base[active]
        pts[:, ax] = x
        vals = _check_margin(margin(pts), len(active))
        evals += len(active)
        fx = vals[np.arange(len(active)), target[active]]
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


def _gauss(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1]."""
    t, w = np.polynomial.legendre.leggauss(order)
    return 0.5 * (t + 1.0), 0.5 * w


ExactColumnsFn = Callable[[np.ndarray, int, float, float],
                          tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
"""(base (M, 2), axis, z0, z1) -> lengths (M, T), errors (M, T), interval ends (M, T), signatures
(M,) int64, inside extent of the last target (M, 2): a margin's exact columns
(`kinematics.mechanisms.p2us.exact.ExactColumns`)."""

Batch = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""(problem index (N,), abscissa (N,)) -> values (N, T), their own error estimates (N, T), and an
integer signature (N, T) that changes where the integrand may be non-smooth (a topology change)."""


def adaptive_1d(f: Batch, a: np.ndarray, b: np.ndarray, rtol: float, atol: float | np.ndarray, *, order: int = 4,
                pieces: int = 8, max_evals: int = 10**8, max_depth: int = 50, group: np.ndarray | None = None,
                floor: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Integrals over [a_p, b_p] of f(p, .) for many problems p at once, adaptively.

    Every interval carries the Gauss-Legendre rule of `order` nodes on itself and on its two
    halves; the halves' sum is its value. Its error estimate is |whole - halves|, plus, where the
    signature differs among the halves' nodes (the integrand may have a kink, a jump or a square
    root edge there, which can make the two rules agree by accident), the variation bound
    width x (max - min of the values at those nodes) -- any rule's error on an interval is at most
    its width times the integrand's range there. The nodes' own errors (an inner integral's) are
    carried along, weighted. Per problem the intervals with the largest estimates are halved until
    the sum is <= max(rtol |integral|, atol) for every target.

    With `group` (P,) (integers 0..G-1) the problems of a group share one tolerance, on the sum
    of their integrals, and the results are per group. With `floor` > 0 every target's tolerance
    is at least rtol x floor x |the last target's integral| (the union's, in a workspace
    measurement): a target far smaller than the last is not chased to a relative tolerance of its own.

    Returns:
        integrals (G, T), error estimates (G, T), converged (G,), evaluations (G = P without groups).
    """
    t, w = _gauss(order)
    gof = np.arange(len(a)) if group is None else np.asarray(group)
    P = int(gof.max()) + 1 if len(gof) else 0
    evals = 0
    atol_arr = np.asarray(atol, dtype=float)
    atol_pt = atol_arr[:, None] if atol_arr.ndim == 1 else atol_arr

    def halves(prob: np.ndarray, lo: np.ndarray, width: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per interval: the halves' rules (C, 2, T), inherited errors (C, T), variation (C, T), topology (C,)."""
        nonlocal evals
        h = 0.5 * width
        x = (np.stack([lo, lo + h], 1)[:, :, None] + h[:, None, None] * t[None, None]).ravel()
        v, e, sig = f(np.repeat(prob, 2 * order), x)
        evals += len(x)
        T = v.shape[1]
        v = v.reshape(len(lo), 2, order, T)
        ww = h[:, None] * w[None]
        q = np.einsum("cn,cknt->ckt", ww, v)
        r = np.einsum("cn,cknt->ct", ww, e.reshape(len(lo), 2, order, T))
        sig = sig.reshape(len(lo), 2 * order, T)
        vv = v.reshape(len(lo), 2 * order, T)
        kinked = np.any(sig != sig[:, :1], axis=1)
        var = np.where(kinked, width[:, None] * (vv.max(axis=1) - vv.min(axis=1)), 0.0)
        return q, r, var, kinked

    width0 = (b - a) / pieces
    prob = np.repeat(np.arange(len(a)), pieces)
    lo = (a[:, None] + width0[:, None] * np.arange(pieces)[None]).ravel()
    width = np.repeat(width0, pieces)
    depth = np.zeros(len(lo), np.int64)
    # the whole-interval rule is the halves' rule one level up: evaluate it directly at the start
    tt = (lo[:, None] + width[:, None] * t[None]).ravel()
    v0, _, _ = f(np.repeat(prob, order), tt)
    evals += len(tt)
    T = v0.shape[1]
    q_self = np.einsum("cn,cnt->ct", width[:, None] * w[None], v0.reshape(-1, order, T))
    q_half, r_in, var, _ = halves(prob, lo, width)
    done_q = np.zeros((P, T))
    done_e = np.zeros((P, T))
    done_in = np.zeros((P, T))
    converged = np.zeros(P, bool)
    while len(lo):
        kid = q_half.sum(axis=1)
        diff = np.abs(q_self - kid) + var  # refinable
        tot_q, tot_e, tot_in = done_q.copy(), done_e.copy(), done_in.copy()
        gp = gof[prob]
        np.add.at(tot_q, gp, kid)
        np.add.at(tot_e, gp, diff)
        np.add.at(tot_in, gp, r_in)
        tol = np.maximum(rtol * np.abs(tot_q), atol_pt)  # (P, T)
        if floor > 0.0:
            tol = np.maximum(tol, rtol * floor * np.abs(tot_q[:, -1:]))
        good = np.all(tot_e + tot_in <= tol, axis=1)
        # the nodes' own (inner) errors alone exceed a target's tolerance: refining here cannot
        # help (they do not shrink with the intervals), so such a problem stops, not converged
        futile = np.any(tot_in > tol, axis=1)
        room = np.maximum(tol - tot_in, 0.0)  # what refinement can still win
        bad = (diff / np.where(room > 0, room, 1.0)[gp]).max(axis=1)
        idx = np.lexsort((bad, gp))
        seg_prob = gp[idx]
        cum = np.cumsum(diff[idx], axis=0)
        starts = np.searchsorted(seg_prob, np.arange(P))
        before = np.concatenate([np.zeros((1, T)), cum])[starts][seg_prob]
        cum = cum - before + done_e[seg_prob]
        ok = np.all(cum <= 0.5 * room[seg_prob], axis=1) | good[seg_prob] | futile[seg_prob]
        accept, refine = idx[ok], idx[~ok]
        stuck = refine[depth[refine] >= max_depth]
        refine = refine[depth[refine] < max_depth]
        last = len(refine) == 0 or evals + 4 * order * len(refine) > max_evals
        if last:
            converged = good
            accept, refine = np.arange(len(lo)), refine[:0]
        else:
            accept = np.concatenate([accept, stuck])
        np.add.at(done_q, gp[accept], kid[accept])
        np.add.at(done_e, gp[accept], diff[accept])
        np.add.at(done_in, gp[accept], r_in[accept])
        if last:
            break
        h = 0.5 * width[refine]
        lo = np.stack([lo[refine], lo[refine] + h], 1).ravel()
        prob, width, depth = np.repeat(prob[refine], 2), np.repeat(h, 2), np.repeat(depth[refine] + 1, 2)
        q_self = q_half[refine].reshape(-1, T)
        q_half, r_in, var, _ = halves(prob, lo, width)
    return done_q, done_e + done_in, converged, evals


def _smoothstep(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """s(t) = 3 t^2 - 2 t^3 on [0, 1] and s'(t): near either end s - s_end ~ 3 t^2, so a
    square-root edge sqrt(x - a) of the integrand becomes analytic in t (the Jacobian 6 t (1 - t)
    vanishes there)."""
    return t * t * (3.0 - 2.0 * t), 6.0 * t * (1.0 - t)


def piecewise_1d(f: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]],
                 a: np.ndarray, b: np.ndarray, n0: int, rtol: float, atol: float | np.ndarray, *,
                 order: int = 4, xtol: float = 1e-10, brk_tol: float | np.ndarray = 0.0,
                 max_evals: int = 10**8, floor: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Integrals over [a_p, b_p] of piecewise smooth f(p, .): breaks located, pieces by Gauss rules.

    f returns values (N, T), their own errors (N, T) and a signature (N,) int64 that is constant
    where f is smooth and changes at its kinks, jumps and square-root edges. Steps:

    1. f on n0 + 1 equally spaced nodes; every pair of neighbours with different signatures
       brackets a break (or several), which bisection narrows until its bracket is below
       xtol x (b - a), or until width x |f(left) - f(right)| <= brk_tol (a square-root edge or a
       kink gets there long before a jump) and the bracket is at most BREAK_WIDTH x the node
       spacing (so that the pieces' nodes do not fall across it). Each break is charged its final bracket's
       width x |f(left) - f(right)|: the two pieces' rules meet at its midpoint.
    2. Each piece [u, v] between consecutive breaks is integrated in t, x = u + (v - u) s(t),
       s = `_smoothstep` (square-root ends become analytic), by `adaptive_1d` with `order` nodes,
       the pieces of a problem sharing its tolerance. A break missed in step 1 (a feature between
       two nodes with equal signatures) shows up as a signature change among an interval's nodes
       and is charged its variation bound; one missed by every node is not seen.

    Returns:
        integrals (P, T), error estimates (P, T), converged (P,), evaluations.
    """
    P = len(a)
    width = b - a
    evals = 0
    prob = np.repeat(np.arange(P), n0 + 1)
    x = (a[:, None] + width[:, None] * (np.arange(n0 + 1) / n0)[None]).ravel()
    x[n0::n0 + 1] = b
    v, _e, sg = f(prob, x)
    evals += len(x)
    sg = sg.reshape(P, n0 + 1)
    X = x.reshape(P, n0 + 1)
    vv = v.reshape(P, n0 + 1, -1)
    bp, bk = np.nonzero(sg[:, 1:] != sg[:, :-1])
    xa, xb, sa, sb, va, vb = X[bp, bk], X[bp, bk + 1], sg[bp, bk], sg[bp, bk + 1], vv[bp, bk], vv[bp, bk + 1]
    tol = xtol * width
    near = BREAK_WIDTH * width / n0
    btol = np.broadcast_to(np.asarray(brk_tol, dtype=float), (P,))
    done: list[tuple[np.ndarray, ...]] = []
    while len(bp) and evals < max_evals:
        fine = ((xb - xa) <= tol[bp]) | (((xb - xa) * np.abs(va - vb).max(axis=1) <= btol[bp])
                                         & ((xb - xa) <= near[bp]))
        if fine.any():
            done.append((bp[fine], xa[fine], xb[fine], va[fine], vb[fine]))
            keep = ~fine
            bp, xa, xb, sa, sb, va, vb = bp[keep], xa[keep], xb[keep], sa[keep], sb[keep], va[keep], vb[keep]
            continue
        xm = 0.5 * (xa + xb)
        vm, _e, sm = f(bp, xm)
        evals += len(xm)
        left, right = sm != sa, sm != sb  # a midpoint unlike both ends: a break on each side
        bp, xa, xb, sa, sb, va, vb = (np.concatenate([p[left], q[right]]) for p, q in (
            (bp, bp), (xa, xm), (xm, xb), (sa, sm), (sm, sb), (va, vm), (vm, vb)))
    if len(bp):  # out of budget: charge what is left as it stands
        done.append((bp, xa, xb, va, vb))
    if done:
        bq, xa, xb, va, vb = (np.concatenate([d[j] for d in done]) for j in range(5))
    else:
        bq, xa, xb, va, vb = np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, vv.shape[2])), np.zeros((0, vv.shape[2]))
    bp = bq.astype(np.int64)
    # pieces between consecutive breaks (bracket midpoints)
    starts = np.concatenate([a, 0.5 * (xa + xb)])
    sprob = np.concatenate([np.arange(P), bp])
    srt = np.lexsort((starts, sprob))
    starts, sprob = starts[srt], sprob[srt]
    ends = np.empty_like(starts)
    ends[:-1] = starts[1:]
    last = np.r_[sprob[1:] != sprob[:-1], True]
    ends[last] = b[sprob[last]]
    u, span = starts, ends - starts

    def g(j: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        st, ds = _smoothstep(t)
        val, err, sig = f(sprob[j], u[j] + span[j] * st)
        jac = (span[j] * ds)[:, None]
        return val * jac, err * jac, np.broadcast_to(sig[:, None], val.shape)

    # the pieces of a problem share its tolerance (a piece with a small integral is not held to a
    # relative tolerance of its own)
    out_q, out_e, ok, ev = adaptive_1d(g, np.zeros(len(u)), np.ones(len(u)), rtol,
                                       np.broadcast_to(np.asarray(atol, dtype=float), (P,)), order=order, pieces=1,
                                       max_evals=max(1, max_evals - evals), group=sprob, floor=floor)
    evals += ev
    if len(bp):
        np.add.at(out_e, bp, (xb - xa)[:, None] * np.abs(va - vb))
    return out_q, out_e, ok & (evals < max_evals), evals


def column_volume(
    margin: Callable[[np.ndarray], np.ndarray],
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    step: float = 0.005,
    rtol: float = 1e-5,
    order: int = 4,
    pieces: int | None = None,
    axis: int | None = None,
    check: bool = False,
    max_points: int = MAX_POINTS,
    progress: bool = False,
    floor: float = 0.0,
    root_tol: float = ROOT_TOL,
    weight: Callable[[np.ndarray], np.ndarray] | None = None,
) -> ColumnVolume:
    """Measure {x in [lo, hi] : margin(x)[:, t] >= 0} for every target t by column integration.

    Args:
        margin: (N, d) points [m] -> (N, T) (or (N,)) margins [m], continuous, >= 0 inside.
        lo: the lower corner [m] of a box containing the region (d = 2 or 3).
        hi: the box's upper corner [m].
        step: [m] exact columns: the quadratures' starting node spacing (at least MIN_NODES
            nodes per direction); sampled columns: the sampling step along the columns
            (components shorter than it can be missed), and 8 x step starts the quadratures.
        rtol: relative tolerance on the error estimate of every target, at least RTOL_FLOOR.
        order: Gauss-Legendre nodes per interval.
        axis: the column axis (default: the box's shortest side).
        check: also run with half the step and compare, halving again while they disagree
            (CHECK_HALVINGS; about 2x the cost when the first two agree).
        max_points: budget of margin evaluations; when it runs out, converged is False.
        floor: every target's tolerance is at least rtol x floor x the last target's measure (for
            a workspace: the union's), so a sliver of a branch is not measured to rtol of its own.
        root_tol: sampled columns: width [m] to which every root is bracketed (at least ROOT_TOL;
            the widths are part of the error estimate).
        weight: (M, d - 1) columns' other coordinates -> (M,) factor on their lengths (sampled
            columns): the measure becomes the integral of weight x length.

    Two optional attributes of the margin change the run: `profile` (3D margins of a solid of
    revolution: `margin`, `lo`, `hi`, `axis`, `weight` and `world_box` of its (rho, z) profile,
    measured instead with the weight 2 pi rho, Pappus) and `for_check()` (the margin the check run
    uses, e.g. a search with more restarts, so that the check also compares two searches).
    """
    profile = getattr(margin, "profile", None)
    if profile is not None and np.asarray(lo).shape == (3,):
        res = column_volume(profile.margin, profile.lo, profile.hi, step=step, rtol=rtol, order=order,
                            pieces=pieces, axis=profile.axis, check=check, max_points=max_points, progress=progress,
                            floor=floor, root_tol=root_tol, weight=profile.weight)
        return replace(res, box=profile.world_box(res.box))
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    d = lo.shape[0]
    if d not in (2, 3) or hi.shape != lo.shape or not np.all(np.isfinite(lo)) or not np.all(hi > lo):
        raise InvalidInputError("box", f"need a finite 2D or 3D box with hi > lo, got {lo.tolist()} .. {hi.tolist()}")
    for name, v in (("step", step), ("rtol", rtol)):
        if not (math.isfinite(v) and v > 0):
            raise InvalidInputError(name, f"must be positive, got {v}")
    if not (math.isfinite(root_tol) and root_tol >= ROOT_TOL):
        raise InvalidInputError("root_tol", f"must be at least ROOT_TOL = {ROOT_TOL:g} m, got {root_tol}")
    if rtol < RTOL_FLOOR:
        raise InvalidInputError("rtol", f"{rtol:g} is too tight a tolerance: at least {RTOL_FLOOR:g} (the roots are "
                                        f"bracketed to {ROOT_TOL:g} m and the quadrature sums in double precision)")
    ax = int(np.argmin(hi - lo)) if axis is None else axis % d
    per_column = math.ceil((hi[ax] - lo[ax]) / step) + 1
    start = per_column * math.prod(3 * order * (pieces or max(1, math.ceil((hi[k] - lo[k]) / (8 * step))))
                                   for k in range(d) if k != ax)
    if start > max_points:
        raise InvalidInputError("step", f"{step:g} m needs {start:,} points to start, over the {max_points:,} limit; "
                                        "use a larger step")
    if _exact_of(margin, d) is not None:
        if weight is not None:
            raise InvalidInputError("weight", "exact columns take no weight")
        run: Callable[..., ColumnVolume] = _run_exact
    else:
        run = partial(_run_sampled, weight=weight, root_tol=root_tol)
    first = run(margin, lo, hi, step, rtol, order, pieces, ax, max_points, progress, floor=floor)
    if not check:
        return first
    for_check = getattr(margin, "for_check", None)
    if for_check is not None:
        margin = for_check()
    def finer(level: int) -> ColumnVolume:
        """The run at step / 2^level (exact columns: at least 2^level x MIN_NODES nodes, so the
        runs differ even where the step exceeds the box)."""
        if run is _run_exact:
            return _run_exact(margin, lo, hi, step / 2**level, rtol, order, pieces, ax, max_points, progress,
                              min_nodes=2**level * MIN_NODES, floor=floor)
        return run(margin, lo, hi, step / 2**level, rtol, order, pieces, ax, max_points, progress, floor=floor)

    columns, points = first.columns, first.points_evaluated
    for level in range(1, CHECK_HALVINGS + 1):
        second = finer(level)
        columns, points = columns + second.columns, points + second.points_evaluated
        diff = np.abs(first.estimate - second.estimate)
        agrees = diff <= first.error + second.error
        # the last target's (the union's) difference enters its error: while it exceeds the
        # tolerance the finer run alone can still meet it (a grazing sliver the coarser run missed)
        settled = agrees.all() and bool(_within(second.estimate, diff, rtol, floor)[-1])
        # a finer run costs about twice the last (sampled columns: twice the samples per column)
        if settled or level == CHECK_HALVINGS or points + 2 * second.points_evaluated > max_points:
            break
        first = second
    error = np.maximum(second.error, diff)
    # every target's own verdict: the runs agree, and the reported error (which includes their
    # difference) is within the tolerance
    per_target = agrees & _within(first.estimate, first.error, rtol, floor) & _within(second.estimate, error, rtol, floor)
    return ColumnVolume(
        estimate=second.estimate, error=error,
        converged=first.converged and second.converged and bool(per_target.all()), rtol=rtol, step=second.step,
        cell=second.cell, columns=columns, points_evaluated=points,
        check_difference=diff,
        box=np.stack([np.fmin(first.box[0], second.box[0]), np.fmax(first.box[1], second.box[1])]),
        target_converged=per_target, check_agrees=agrees, root_tol=second.root_tol,
    )


def _exact_of(margin: Callable[[np.ndarray], np.ndarray], d: int) -> ExactColumnsFn | None:
    """The margin's exact column function (3D margins that provide `exact_columns`), or None."""
    fn = getattr(margin, "exact_columns", None)
    return fn if (fn is not None and d == 3) else None


def _run_exact(margin: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, step: float, rtol: float,
               order: int, pieces: int | None, axis: int | None, max_points: int, progress: bool,
               min_nodes: int = MIN_NODES, floor: float = 0.0) -> ColumnVolume:
    """Exact columns (no sampling): slices by `piecewise_1d`, the volume by `adaptive_1d`."""
    d = 3
    exact = _exact_of(margin, d)
    assert exact is not None
    ax = int(np.argmin(hi - lo)) if axis is None else axis % d
    k_out, k_in = [k for k in range(d) if k != ax]
    counter = _Counter(d)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(desc="volume", unit="col", unit_scale=True, delay=1.0, leave=False)

    def n_nodes(k: int) -> int:
        return pieces or max(min_nodes, math.ceil((hi[k] - lo[k]) / step))

    def columns(base: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ell, err, ends, sig, zb = exact(base, ax, lo[ax], hi[ax])
        counter.columns += len(base)
        counter.points += int(ends.sum()) + 2 * len(base)
        found = np.isfinite(zb[:, 0])
        if found.any():
            p = np.empty((int(found.sum()), d))
            p[:, k_out], p[:, k_in] = base[found, 0], base[found, 1]
            for z in (zb[found, 0], zb[found, 1]):
                p[:, ax] = z
                counter.lo = np.minimum(counter.lo, p.min(axis=0))
                counter.hi = np.maximum(counter.hi, p.max(axis=0))
        if bar is not None:
            bar.update(len(base))
        return ell, err, sig

    all_conv = [True]
    inner_rtol = 0.25 * rtol  # the slices' errors add up to <= rtol / 4 of the volume
    face = (hi[k_in] - lo[k_in]) * (hi[ax] - lo[ax])
    # slices below this area [m^2] need no relative accuracy: the volume's tolerance covers them
    atol_in = 1e-3 * rtol * face / n_nodes(k_out)
    brk_in = 2e-3 * rtol * face  # per located break: well below any slice's share of the tolerance

    def inner(x: np.ndarray) -> Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]:
        def f(p: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            base = np.empty((len(p), 2))
            base[:, 0], base[:, 1] = x[p], y
            return columns(base)
        return f

    def slice_area(_: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        P = len(x)
        # the budget is shared by every slice: what is left of it
        a, ea, c, _ev = piecewise_1d(inner(x), np.full(P, lo[k_in]), np.full(P, hi[k_in]), n_nodes(k_in),
                                     inner_rtol, atol_in, order=order, brk_tol=brk_in,
                                     max_evals=max(1, max_points - counter.columns), floor=floor)
        all_conv[0] &= bool(c.all())
        return a, ea, np.zeros(a.shape, np.int64)

    # the outer integral by adaptive Gauss rules on |whole - halves| alone: A(x) is continuous
    # except at faces normal to x, and locating its breaks (where the slices' sequence of
    # signatures changes) measured 5-20x dearer than refining around them
    q, e, conv, _ = adaptive_1d(slice_area, lo[[k_out]], hi[[k_out]], rtol, 0.0, order=order,
                                pieces=math.ceil(n_nodes(k_out) / OUTER_SPAN), max_evals=max_points, floor=floor)
    if bar is not None:
        bar.close()
    box = np.stack([counter.lo, counter.hi])
    return ColumnVolume(
        estimate=q[0], error=e[0],
        converged=bool(conv[0]) and all_conv[0] and counter.columns <= max_points and bool(q[0, -1] > 0),
        rtol=rtol, step=step, cell=step, columns=counter.columns, points_evaluated=counter.points,
        check_difference=np.full(q.shape[1], np.nan), box=np.where(np.isfinite(box), box, np.nan),
        target_converged=_within(q[0], e[0], rtol, floor), check_agrees=np.ones(q.shape[1], bool),
    )


def _run_sampled(margin: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, step: float, rtol: float,
         order: int, pieces: int | None, axis: int | None, max_points: int, progress: bool,
         floor: float = 0.0, root_tol: float = ROOT_TOL,
         weight: Callable[[np.ndarray], np.ndarray] | None = None) -> ColumnVolume:
    d = lo.shape[0]
    ax = int(np.argmin(hi - lo)) if axis is None else axis % d
    others = [k for k in range(d) if k != ax]
    counter = _Counter(d)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(desc="volume", unit="col", unit_scale=True, delay=1.0, leave=False)

    def n_pieces(k: int) -> int:
        return pieces or max(1, math.ceil((hi[k] - lo[k]) / (8 * step)))

    def columns(base: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ell, err, ends = column_lengths(margin, base, lo[ax], hi[ax], step, ax, counter, root_tol)
        if weight is not None:
            w = np.asarray(weight(base), dtype=float)[:, None]
            ell, err = ell * w, err * w
        if bar is not None:
            bar.update(len(base))
        return ell, err, ends

    budget = max(1, max_points // max(1, math.ceil((hi[ax] - lo[ax]) / step) + 1))
    inner_rtol = 0.25 * rtol  # the slices' errors add up to <= rtol / 4 of the volume
    if d == 2:
        q, e, conv, _ = adaptive_1d(lambda p, x: columns(x[:, None]), lo[others[:1]], hi[others[:1]], rtol, 0.0,
                                    order=order, pieces=n_pieces(others[0]), max_evals=budget, floor=floor)
    else:
        k_out, k_in = others
        all_conv = [True]
        # slices below this area [m^2] need no relative accuracy: the volume's tolerance covers them
        atol_in = 1e-3 * rtol * (hi[k_in] - lo[k_in]) * step

        def slice_area(_: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            P = len(x)

            def inner(p: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                return columns(np.stack([x[p], y], axis=1))

            a, ea, c, _evals = adaptive_1d(inner, np.full(P, lo[k_in]), np.full(P, hi[k_in]), inner_rtol, atol_in,
                                      order=order, pieces=n_pieces(k_in), max_evals=budget, floor=floor)
            all_conv[0] &= bool(c.all())
            return a, ea, (a > 0).astype(np.int64)

        q, e, conv, _ = adaptive_1d(slice_area, lo[[k_out]], hi[[k_out]], rtol, 0.0, order=order,
                                    pieces=n_pieces(k_out), max_evals=budget, floor=floor)
        conv = conv & all_conv[0]
    if bar is not None:
        bar.close()
    box = np.stack([counter.lo, counter.hi])
    return ColumnVolume(
        # finding nothing cannot be told from sampling past everything: never a confident 0
        estimate=q[0], error=e[0], converged=bool(np.all(conv)) and counter.columns <= budget and bool(q[0, -1] > 0),
        rtol=rtol,
        step=step, cell=8 * step, columns=counter.columns,
        points_evaluated=counter.points, check_difference=np.full(q.shape[1], np.nan),
        box=np.where(np.isfinite(box), box, np.nan),
        target_converged=_within(q[0], e[0], rtol, floor), check_agrees=np.ones(q.shape[1], bool), root_tol=root_tol,
    )
