"""A solid turned through part of a turn: |W| = (L / 2 pi) |W_P| + X (see
`kinematics.mechanisms.serial.turn`), |W_P| the full turn's solid measured on its profile by the
engine and X = integral over the profile box of a circle-measure integrand g(r, z): columns along
z at the nodes of the engine's `adaptive_1d` over r, each column's inside intervals by
`piecewise_1d` (the circles' kind changes bisected one circle per halving), the same error
estimate; checked the same way: a second run at half the step (the circles sampled twice as
finely, through the margin's check search), their difference part of the error, `converged`
false when they disagree beyond their estimates.

Every run is bounded in reach searches (SEARCHES; a circle costs ~2 pi r / step of them), both
rules pricing their rounds in searches; the first run climbs a ladder of tolerances (`ladder`)
so that a run out of budget still answers with the last complete rung's estimate."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from .quadrature import adaptive_1d, piecewise_1d

SPAN = 8
"""The outer integral's starting intervals along r are SPAN x step wide (the engine's sampled columns' 8 x step)."""

FINEST = 1 / 64
"""No interval of the outer rule (over r) is halved below FINEST x step: whether a part of S
shorter than the step is seen depends on the sampling and the search (the check run's
business); below that scale the intervals are accepted with their estimates, not refined without
end. (The columns' kind changes are bisected to BREAK_TOL: one circle per halving.)"""

SEARCHES = 2_000_000
"""The first run of the integral stops refining after this many reach searches (or the
engine's `max_points`, if smaller; the check run after CHECK_BUDGET x as many), not converged: a
point of a circle's arc set costs 2 pi r / step searches (~200 on the so100 at the CLI's 1 cm),
so a budget counted in columns or points says nothing of the time (the so100's first run spent
1.7e6 searches in 86 s at load 6 on 2 cores, docs/serial-workspace.md)."""

BRACKET_SHARE = 0.01
"""The share of the integral's `atol` the root brackets (the circles' gap ends, the columns'
ends) may take at most: bisecting them to the engine's 1e-12 m cost ~33 rounds of searches per
end, ~15 at this share for the so100 at rtol 1e-3."""

NODES = 8
"""A column's inside interval starts with NODES + 1 equally spaced points (`piecewise_1d`): the
circles' kind changes between them are bisected one circle per halving, where a halving of
`adaptive_1d` costs 8 circles."""

BREAK_TOL = 1e-7
"""[m] A kind change is bisected until its bracket times the integrand's jump is within a tenth of
the interval's share of the tolerance, or to BREAK_TOL: a part of S appearing makes c jump by up
to w (the largest gap split), so a bracket of step / 64 held ~1e-4 m^2 per change on the so100,
over the whole tolerance at rtol 1e-3."""

COVER_COST = 20_000
"""Searches of `cover_bound`'s count (a profile search and a cover search at each of 10 000 points)."""

CHECK_BUDGET = 2
"""The check run (half the step: each circle and column sampled twice as finely) may spend this
many times the first run's budget."""

LADDER_START, LADDER_FACTOR = 1e-2, 4.0
"""`ladder`'s first tolerance and its ratio: a run at rtol 1e-3 from the start spent the so100's
budget on the first columns' inner rules (~14 000 searches a column) and ended further from X
(+-2e-3 m^3) than a complete run at 1e-2 (+-1.9e-4 m^3 in fewer searches)."""

BISECTIONS = 60
"""Most bisections of a column's root bracket (from the step down to the root tolerance: ~20)."""


def _intervals(margin: Callable[[np.ndarray], np.ndarray], r: np.ndarray, z0: float, z1: float, step: float,
               root_tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The inside intervals of the profile margin along the columns at r (M,) over [z0, z1]: their
    columns (K,), ends (K,), (K,) [m], the ends' bracket widths (K,) [m] (0 on the box's faces) and
    the evaluations spent. Sampled every `step`, each sign change bisected to `root_tol`."""
    n = max(1, math.ceil((z1 - z0) / step - 1e-9))
    zs = np.linspace(z0, z1, n + 1)
    M = len(r)
    vals = np.asarray(margin(np.column_stack([np.repeat(r, n + 1), np.tile(zs, M)])), float).reshape(M, n + 1)
    ins = vals >= 0
    spent = M * (n + 1)
    c, k = np.nonzero(ins[:, :-1] != ins[:, 1:])
    a, b = zs[k], zs[k + 1]  # a: the inside end
    flip = ~ins[c, k]
    a, b = np.where(flip, b, a), np.where(flip, a, b)
    for _ in range(BISECTIONS):
        act = np.flatnonzero(np.abs(b - a) > root_tol)
        if not len(act):
            break
        mid = 0.5 * (a[act] + b[act])
        ok = np.asarray(margin(np.column_stack([r[c[act]], mid])), float).reshape(-1) >= 0
        spent += len(act)
        a[act], b[act] = np.where(ok, mid, a[act]), np.where(ok, b[act], mid)
    cols = np.concatenate([c, np.flatnonzero(ins[:, 0]), np.flatnonzero(ins[:, -1])])
    ends = np.concatenate([0.5 * (a + b), np.full(int(ins[:, 0].sum()), z0), np.full(int(ins[:, -1].sum()), z1)])
    width = np.concatenate([np.abs(b - a), np.zeros(int(ins[:, 0].sum() + ins[:, -1].sum()))])
    order = np.lexsort((ends, cols))
    cols, ends, width = cols[order].reshape(-1, 2), ends[order].reshape(-1, 2), width[order].reshape(-1, 2)
    return cols[:, 0], ends[:, 0], ends[:, 1], width.sum(axis=1), spent


def integrate_turn(g: Any, lo: np.ndarray, hi: np.ndarray, step: float, cell: float, atol: float, rtol: float,
                   root_tol: float, budget: int, order: int = 4) -> tuple[float, float, bool, int, int]:
    """X = integral of g over the profile box [lo, hi] (2,) [m] to max(rtol |X|, atol): columns
    along z at the nodes of an adaptive rule over r (starting intervals `cell` [m] wide), each
    column's inside intervals of the profile (`g.margin`, sampled every `step` [m], ends bisected to
    `root_tol`) integrated by an adaptive rule of their own (g is continuous inside the profile, and
    falls to 0 at its boundary only where the arc sets shrink to points), the ends' brackets times
    the integrand's bound r w in the error (the brackets narrowed only to a BRACKET_SHARE of
    `atol` over the box: each halving is a search per end, a circle's end one of many). `budget` bounds the searches (both rules price their
    rounds in searches, `adaptive_1d`'s `cost`): when it runs out every interval is accepted with
    its estimate, converged False. Returns the value [m^3], its error estimate, converged, columns
    and searches spent."""
    spent = [0, 0]
    # the brackets' errors (charged in full) need not be narrower than a share of the tolerance:
    # the ends of the circles' gaps to `arc_tol` [m of arc] (<= 2 arc_tol per point over the box's
    # area), the columns' ends to `end_tol` (<= end_tol r w per column over the r range)
    area = float((hi[0] - lo[0]) * (hi[1] - lo[1]))
    arc_tol = max(root_tol, BRACKET_SHARE * atol / (2 * area))
    end_tol = max(root_tol, BRACKET_SHARE * atol / (2 * g.w * float(hi[0]) * float(hi[0] - lo[0])))

    def depth(width: float) -> int:
        """Halvings from `width` [m] down to FINEST x step."""
        return max(1, math.ceil(math.log2(max(width, step) / (FINEST * step))))

    atol_in = 0.25 * atol / (hi[0] - lo[0])  # the columns' errors add up to <= atol / 4 over r

    def column(_: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        M = len(r)
        c, za, zb, width, n = _intervals(g.margin, r, lo[1], hi[1], step, end_tol)
        spent[0] += M
        spent[1] += n
        value, error = np.zeros(M), np.zeros(M)
        if len(c):
            def f(p: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                v, e, sig, used = g(np.column_stack([r[c[p]], z]), step, arc_tol)
                spent[1] += used
                return v[:, None], e[:, None], sig

            before = spent[1]
            # the outer rule prices its rounds so as to stay within the budget; a column cut short
            # would carry its first rules' errors into the result, so the columns may overrun it,
            # up to twice the budget in all
            room, counter = max(2 * budget - before, 0), (lambda: spent[1] - before)
            # each interval its share of the column's tolerance, by length
            share = (zb - za) / np.bincount(c, zb - za, minlength=M)[c]
            q, e, _ok, _n = piecewise_1d(f, za, zb, NODES, 0.25 * rtol, atol_in * share, order=order,
                                         xtol=BREAK_TOL / max(float((zb - za).max()), step),
                                         brk_tol=0.1 * atol_in * share, max_evals=room, cost=counter)
            q, e = np.bincount(c, q[:, 0], minlength=M)[:, None], np.bincount(c, e[:, 0], minlength=M)[:, None]
            G = len(q)
            value[:G] += q[:, 0]
            error[:G] += e[:, 0] + np.bincount(c, width * r[c] * g.w, minlength=G)[:G]
        return value[:, None], error[:, None], np.bincount(c, minlength=M)[:, None].astype(np.int64)

    pieces = max(1, math.ceil((hi[0] - lo[0]) / cell))
    q, e, conv, _ = adaptive_1d(column, lo[:1], hi[:1], rtol, atol, order=order, pieces=pieces, max_evals=budget,
                                max_depth=depth((hi[0] - lo[0]) / pieces), cost=lambda: spent[1])
    # a column's own tolerance is a device: its errors are carried into the outer rule's, which judges
    ok = bool(conv.all())
    return float(q[0, 0]), float(e[0, 0]), ok, spent[0], spent[1]


def ladder(g: Any, lo: np.ndarray, hi: np.ndarray, step: float, base: float, rtol: float, root_tol: float,
           budget: int, top: float | None = None, taken: float = 0.0) -> tuple[float, float, bool, int, int, float]:
    """X by `integrate_turn` at tolerances LADDER_START, / LADDER_FACTOR, ... down to `rtol` (of
    the volume: X's atol at a tolerance t what t x `base` [m^3], (L / 2 pi) |W_P|, leaves after
    `taken` [m^3], the full turn's share of the error, and at least a quarter of t x base), each
    run on the budget's rest, the next started only while at least the last run's searches remain
    (it may be cut short). The run with the smallest error estimate is the answer (a run cut short keeps its
    honest estimate: it may still beat the last complete one); with `top` (the check run: the
    tolerance the first run reached) one run at it. Returns X [m^3], its error, converged at
    `rtol`, columns and searches spent (all runs), the tightest tolerance completed."""
    tol = max(rtol, min(LADDER_START, top)) if top is not None else max(rtol, LADDER_START)
    best: tuple[float, float, bool] | None = None
    columns = searches = 0
    reached = math.inf
    while True:
        atol = max(0.25 * tol * max(base, 1e-300), 0.9 * (tol * base - taken))
        x, e, ok, n, used = integrate_turn(g, lo, hi, step, SPAN * step, atol, tol, root_tol, budget - searches)
        columns, searches = columns + n, searches + used
        if ok:
            reached = tol
        if best is None or e < best[1]:
            best = (x, e, ok and tol <= rtol * (1 + 1e-12))
        last = tol <= max(rtol, top if top is not None else 0.0) * (1 + 1e-12)
        if last or not ok or budget - searches < used:
            return best[0], best[1], best[2], columns, searches, reached
        tol = max(rtol, tol / LADDER_FACTOR)


def cover_bound(res: Any, turn: Any) -> Any | None:
    """The partial turn's volume from the full turn's `res` by the cover bound, when that meets
    the tolerance: V_P - k D within res.error + k (D + 4 sd), k = w / 4 pi, D and sd
    (`turn.uncovered()`) the measure of the profile whose circles the cover test cannot prove
    whole and its standard error: a Monte-Carlo count of 10 000 searches, where the circles'
    integral costs millions (the panda: uncovered circles in a thin ring near its reach, the
    answer in ~20 s). None when the bound is too wide (the z1, the so100)."""
    D, sd = turn.uncovered()
    k = turn.w / (4 * math.pi)
    volume = float(res.estimate[-1]) - k * D
    error = float(res.error[-1]) + k * (D + 4 * sd)
    if not (bool(res.target_converged[-1]) and error <= res.rtol * abs(volume) * (1 + 1e-12)):
        return None
    return replace(res, estimate=np.array([volume]), error=np.array([error]),
                   fixed_error=np.array([k * (D + 4 * sd)]), points_evaluated=res.points_evaluated + COVER_COST)


def add_turn(res: Any, turn: Any, lo: np.ndarray, hi: np.ndarray, step: float, check: bool, max_points: int,
             root_tol: float) -> Any:
    """The partial turn's volume from the full turn's `res` (a `ColumnVolume` of one target, the
    solid |W_P|): (L / 2 pi) |W_P| + X, the error (L / 2 pi) res.error + X's; with `check`, X also at
    half the step through `turn.for_check()`, their difference in the error and their agreement in
    `converged`. `turn`: `.range` L [rad], `.w` = 2 pi - L, `.margin` the profile's margin and the integrand
    (`kinematics.mechanisms.serial.turn.TurnExtent`)."""
    f = turn.range / (2 * math.pi)
    base = f * float(res.estimate[-1])
    budget = min(max_points, SEARCHES)
    bound = cover_bound(res, turn)
    if bound is not None:
        return bound
    taken = f * float(res.error[-1])
    x1, e1, c1, n1, s1, level = ladder(turn, lo, hi, step, base, res.rtol, root_tol, budget, taken=taken)
    x, err, conv, agrees, diff = x1, e1, c1, True, math.nan
    points, columns = s1, n1
    if check:  # up to the tolerance the first run reached: the comparison needs no more
        x2, e2, c2, n2, s2, _ = ladder(turn.for_check(), lo, hi, step / 2, base, res.rtol, root_tol,
                                       CHECK_BUDGET * budget, top=level, taken=taken)
        diff = abs(x1 - x2)
        agrees = diff <= e1 + e2
        x, err, conv, points, columns = x2, max(e2, diff), c1 and c2, s1 + s2, n1 + n2
    estimate = np.array([base + x])
    error = np.array([f * float(res.error[-1]) + err])
    ok = bool(res.target_converged[-1]) and conv and agrees and bool(error[0] <= res.rtol * estimate[0] * (1 + 1e-12))
    spent_out = not conv and points >= budget  # X stopped on its budget, not on its tolerance
    return replace(res, estimate=estimate, error=error, converged=bool(res.converged) and ok,
                   target_converged=np.array([ok]), check_agrees=np.array([bool(res.check_agrees[-1]) and agrees]),
                   check_difference=np.array([f * float(res.check_difference[-1]) + diff]),
                   points_evaluated=res.points_evaluated + points, columns=res.columns + columns,
                   out_of_budget=np.array([spent_out and not ok]))
