"""Adaptive Gauss-Legendre quadrature of many 1-D integrals at once, plain (`adaptive_1d`) or
piecewise between located breaks of a signature (`piecewise_1d`); see the package docstring."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

BREAK_WIDTH = 1e-3
"""`piecewise_1d`: a located break's bracket is at most this fraction of the node spacing (or
narrower than xtol). Under the pieces' grading a bracket of relative width w spans ~sqrt(w / 3) of
the rule's variable at the piece's end, so a wider one puts the first levels' Gauss nodes across
the break, whose variation bound then refines there level by level; bisecting a break 10 more
times (one column each) measured 1.8-2.6x fewer columns in all on p2us and the Delta, and a
smaller error estimate."""


def _gauss(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on [0, 1]."""
    t, w = np.polynomial.legendre.leggauss(order)
    return 0.5 * (t + 1.0), 0.5 * w


Batch = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""(problem index (N,), abscissa (N,)) -> values (N, T), their own error estimates (N, T), and an
integer signature (N, T) that changes where the integrand may be non-smooth (a topology change)."""


def adaptive_1d(f: Batch, a: np.ndarray, b: np.ndarray, rtol: float, atol: float | np.ndarray, *, order: int = 4,
                pieces: int = 8, max_evals: int = 10**8, max_depth: int = 50, group: np.ndarray | None = None,
                floor: float = 0.0, cost: Callable[[], int] | None = None, ends: bool = False
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Integrals over [a_p, b_p] of f(p, .) for many problems p at once, adaptively.

    Every interval carries the Gauss-Legendre rule of `order` nodes on itself and on its two
    halves; the halves' sum is its value. Its error estimate is |whole - halves|, plus, where the
    signature differs among the halves' nodes (the integrand may have a kink, a jump or a square
    root edge there, which can make the two rules agree by accident), the variation bound
    width x (max - min of the values at those nodes) -- any rule's error on an interval is at most
    its width times the integrand's range there. With `ends` the interval's two end points join that
    test (f at the pieces' ends, then once at each halved interval's middle, shared by its
    children): where an end's signature differs from its nearest node's alone, the change lies in
    the gap between them (h t_min, ~3.5 % of the width), charged gap x |f(end) - f(node)|. Gauss
    nodes never reach an interval's ends, so without them a jump in the last ~7 % of a half,
    between two intervals' outermost nodes, leaves both intervals smooth on their nodes and is
    charged nothing (an indicator of [0, 0.3] over [-0.0363, 0.3352] in 5 pieces: 0.05983 for
    0.06, an error estimate of 7.8e-6 for 1.7e-4). The nodes' own errors (an inner integral's) are
    carried along, weighted. Per problem the intervals with the largest estimates are halved until
    the sum is <= max(rtol |integral|, atol) for every target.

    With `group` (P,) (integers 0..G-1) the problems of a group share one tolerance, on the sum
    of their integrals, and the results are per group. With `floor` > 0 every target's tolerance
    is at least rtol x floor x |the last target's integral| (the union's, in a workspace
    measurement): a target far smaller than the last is not chased to a relative tolerance of its own.

    With `cost` (a counter of what f has spent so far, e.g. searches, when an evaluation's price
    varies) `max_evals` bounds that count instead of the evaluations: a round is priced at the
    mean cost per evaluation so far, and when the next round would overrun it only the intervals
    with the largest estimates that fit are halved (the rest accepted as they stand: the mean
    cost and the last round's, whichever is dearer, price a round), so the
    budget is spent where the error is; when not even one fits, every interval is accepted with
    its estimate and the run ends, not converged.

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
        sig = np.asarray(sig).reshape(len(lo), 2 * order, -1)
        vv = v.reshape(len(lo), 2 * order, T)
        kinked = np.any(sig != sig[:, :1], axis=1)
        if not ends:
            var = np.where(kinked, width[:, None] * (vv.max(axis=1) - vv.min(axis=1)), 0.0)
            return q, r, var, kinked
        # the end points (`ends`): a break between the nodes is charged the whole width x the
        # range; one only between an end and its nearest node lies within that gap (h t_min wide),
        # where the rule's smooth extension is off by at most about their difference
        allv = np.concatenate([end_val[:, 0, None], vv, end_val[:, 1, None]], axis=1)
        gap = h[:, None] * float(t.min())
        edge = sum(np.where(end_sig[:, k] != sig[:, -k], gap * np.abs(end_val[:, k] - vv[:, -k]), 0.0)
                   for k in (0, 1))
        var = np.where(kinked, width[:, None] * (allv.max(axis=1) - allv.min(axis=1)), edge)
        return q, r, var, kinked | np.any(end_sig != sig[:, [0, -1]], axis=1)

    def at(prob: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """f's values (N, T) and signatures (N, S) at points x (N,) of problems prob."""
        nonlocal evals
        v, _, sig = f(prob, x)
        evals += len(x)
        return v, np.asarray(sig).reshape(len(x), -1)

    width0 = (b - a) / pieces
    prob = np.repeat(np.arange(len(a)), pieces)
    lo = (a[:, None] + width0[:, None] * np.arange(pieces)[None]).ravel()
    width = np.repeat(width0, pieces)
    depth = np.zeros(len(lo), np.int64)
    end_val = end_sig = np.zeros((0, 2, 0))
    if ends:  # f at every piece's ends, once per point: (C, 2, T) values, (C, 2, S) signatures
        k = np.arange(pieces + 1)
        ev, es = at(np.repeat(np.arange(len(a)), pieces + 1), (a[:, None] + width0[:, None] * k[None]).ravel())
        ev, es = ev.reshape(len(a), pieces + 1, -1), es.reshape(len(a), pieces + 1, -1)
        end_val = np.stack([ev[:, :-1], ev[:, 1:]], axis=2).reshape(len(lo), 2, -1)
        end_sig = np.stack([es[:, :-1], es[:, 1:]], axis=2).reshape(len(lo), 2, -1)
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
    last_round = (0, 0)  # (cost, evaluations) when the last round's evaluations began
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
        if cost is None:
            last = len(refine) == 0 or evals + 4 * order * len(refine) > max_evals
        else:
            now = cost()
            # priced at the dearer of the mean and the last round's (refined intervals lie where
            # evaluations cost most)
            per = max(now / max(evals, 1), (now - last_round[0]) / max(evals - last_round[1], 1))
            last_round = (now, evals)
            refine, spill = _affordable(refine, bad, per, now, 4 * order, max_evals)
            accept = np.concatenate([accept, spill])
            last = len(refine) == 0
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
        if ends:  # f at each halved interval's middle: its children's shared end
            mv, ms = at(prob[refine], lo[refine] + h)
            end_val = np.stack([end_val[refine, 0], mv, mv, end_val[refine, 1]], axis=1).reshape(-1, 2, mv.shape[1])
            end_sig = np.stack([end_sig[refine, 0], ms, ms, end_sig[refine, 1]], axis=1).reshape(-1, 2, ms.shape[1])
        lo = np.stack([lo[refine], lo[refine] + h], 1).ravel()
        prob, width, depth = np.repeat(prob[refine], 2), np.repeat(h, 2), np.repeat(depth[refine] + 1, 2)
        q_self = q_half[refine].reshape(-1, T)
        q_half, r_in, var, _ = halves(prob, lo, width)
    return done_q, done_e + done_in, converged, evals


def _affordable(refine: np.ndarray, bad: np.ndarray, per: float, spent: int, per_interval: int, budget: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """The intervals `refine` split into those the budget can still halve (the largest `bad`
    first, each priced per_interval evaluations at `per` apiece, `spent` spent) and the rest."""
    price = per_interval * per
    fit = int((budget - spent) // price) if price > 0 else len(refine)
    if fit >= len(refine):
        return refine, refine[:0]
    order = refine[np.argsort(-bad[refine], kind="stable")]
    return order[:max(fit, 0)], order[max(fit, 0):]


def _smoothstep(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """s(t) = 3 t^2 - 2 t^3 on [0, 1] and s'(t): near either end s - s_end ~ 3 t^2, so a
    square-root edge sqrt(x - a) of the integrand becomes analytic in t (the Jacobian 6 t (1 - t)
    vanishes there)."""
    return t * t * (3.0 - 2.0 * t), 6.0 * t * (1.0 - t)


def piecewise_1d(f: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]],
                 a: np.ndarray, b: np.ndarray, n0: int, rtol: float, atol: float | np.ndarray, *,
                 order: int = 4, xtol: float = 1e-10, brk_tol: float | np.ndarray = 0.0,
                 max_evals: int = 10**8, floor: float = 0.0, cost: Callable[[], int] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
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

    With `cost` (a counter of what f has spent, as `adaptive_1d`'s) `max_evals` bounds that count.

    Returns:
        integrals (P, T), error estimates (P, T), converged (P,), evaluations.
    """
    P = len(a)
    evals = 0

    def count() -> int:
        return evals if cost is None else cost()

    width = b - a
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
    while len(bp) and count() < max_evals:
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
    before = count()
    out_q, out_e, ok, ev = adaptive_1d(g, np.zeros(len(u)), np.ones(len(u)), rtol,
                                       np.broadcast_to(np.asarray(atol, dtype=float), (P,)), order=order, pieces=1,
                                       max_evals=max(1, max_evals - before), group=sprob, floor=floor,
                                       cost=None if cost is None else (lambda: cost() - before))
    evals += ev
    if len(bp):
        np.add.at(out_e, bp, (xb - xa)[:, None] * np.abs(va - vb))
    return out_q, out_e, ok & (count() < max_evals), evals


