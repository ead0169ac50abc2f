"""A solid turned through part of a turn: |W| = (L / 2 pi) |W_P| + X (see
`kinematics.mechanisms.serial.turn`), |W_P| the full turn's solid measured on its profile by the
engine and X = integral over the profile box of a circle-measure integrand g(r, z), integrated
here by the engine's nested `adaptive_1d` (the same error estimate) and checked the same way: a
second run at half the step (the circles sampled twice as finely, through the margin's check
search; the same starting intervals, the quadrature's own estimate covering the integration of
this continuous integrand: doubling them too cost 7x the first run on the 3R test arm), their
difference part of the error, `converged` false when they disagree beyond their estimates."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from .quadrature import adaptive_1d

SPAN = 8
"""The outer integral's starting intervals along r are SPAN x step wide (the engine's sampled columns' 8 x step)."""

FINEST = 1 / 64
"""No interval of either rule is halved below FINEST x step: the circles' measure jumps where a
part of S appears, and whether a part shorter than the step is seen depends on the sampling and
the search (the check run's business); below that scale the intervals are accepted with their
estimates (the jump's variation over a width <= step / 64 counted), not refined without end."""

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
                   root_tol: float, max_points: int, order: int = 4) -> tuple[float, float, bool, int, int]:
    """X = integral of g over the profile box [lo, hi] (2,) [m] to max(rtol |X|, atol): columns
    along z at the nodes of an adaptive rule over r (starting intervals `cell` [m] wide), each
    column's inside intervals of the profile (`g.margin`, sampled every `step` [m], ends bisected to
    `root_tol`) integrated by an adaptive rule of their own (g is continuous inside the profile, and
    falls to 0 at its boundary only where the arc sets shrink to points), the ends' brackets times
    the integrand's bound r w in the error. Returns the value [m^3], its error estimate,
    converged, columns and searches spent."""
    spent = [0, 0]

    def depth(width: float) -> int:
        """Halvings from `width` [m] down to FINEST x step."""
        return max(1, math.ceil(math.log2(max(width, step) / (FINEST * step))))

    atol_in = 0.25 * atol / (hi[0] - lo[0])  # the columns' errors add up to <= atol / 4 over r

    def column(_: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        M = len(r)
        c, za, zb, width, n = _intervals(g.margin, r, lo[1], hi[1], step, root_tol)
        spent[0] += M
        spent[1] += n
        value, error = np.zeros(M), np.zeros(M)
        if len(c):
            def f(p: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                v, e, sig, used = g(np.column_stack([r[c[p]], z]), step, root_tol)
                spent[1] += used
                return v[:, None], e[:, None], sig[:, None]

            # a column's intervals share its tolerance (group)
            q, e, _ok, _n = adaptive_1d(f, za, zb, 0.25 * rtol, atol_in, order=order, pieces=1,
                                       max_evals=max_points, group=c, max_depth=depth(float((zb - za).max())))
            G = len(q)
            value[:G] += q[:, 0]
            error[:G] += e[:, 0] + np.bincount(c, width * r[c] * g.w, minlength=G)[:G]
        return value[:, None], error[:, None], np.bincount(c, minlength=M)[:, None].astype(np.int64)

    pieces = max(1, math.ceil((hi[0] - lo[0]) / cell))
    q, e, conv, _ = adaptive_1d(column, lo[:1], hi[:1], rtol, atol, order=order, pieces=pieces, max_evals=max_points,
                                max_depth=depth((hi[0] - lo[0]) / pieces))
    # a column's own tolerance is a device: its errors are carried into the outer rule's, which judges
    ok = bool(conv.all()) and spent[1] <= max_points
    return float(q[0, 0]), float(e[0, 0]), ok, spent[0], spent[1]


def add_turn(res: Any, turn: Any, lo: np.ndarray, hi: np.ndarray, step: float, check: bool, max_points: int,
             root_tol: float) -> Any:
    """The partial turn's volume from the full turn's `res` (a `ColumnVolume` of one target, the
    solid |W_P|): (L / 2 pi) |W_P| + X, the error (L / 2 pi) res.error + X's; with `check`, X also at
    half the step through `turn.for_check()`, their difference in the error and their agreement in
    `converged`. `turn`: `.range` L [rad], `.w` = 2 pi - L, `.margin` the profile's margin and the integrand
    (`kinematics.mechanisms.serial.turn.TurnExtent`)."""
    f = turn.range / (2 * math.pi)
    base = f * float(res.estimate[-1])
    # X's share of the tolerance: a quarter of the volume's (|W| >= f |W_P|)
    atol = 0.25 * res.rtol * max(base, 1e-300)
    x1, e1, c1, n1, s1 = integrate_turn(turn, lo, hi, step, SPAN * step, atol, res.rtol, root_tol, max_points)
    x, err, conv, agrees, diff = x1, e1, c1, True, math.nan
    points, columns = s1, n1
    if check:
        x2, e2, c2, n2, s2 = integrate_turn(turn.for_check(), lo, hi, step / 2, SPAN * step, atol, res.rtol, root_tol, max_points)
        diff = abs(x1 - x2)
        agrees = diff <= e1 + e2
        x, err, conv, points, columns = x2, max(e2, diff), c1 and c2, s1 + s2, n1 + n2
    estimate = np.array([base + x])
    error = np.array([f * float(res.error[-1]) + err])
    ok = bool(res.target_converged[-1]) and conv and agrees and bool(error[0] <= res.rtol * estimate[0] * (1 + 1e-12))
    return replace(res, estimate=estimate, error=error, converged=bool(res.converged) and ok,
                   target_converged=np.array([ok]), check_agrees=np.array([bool(res.check_agrees[-1]) and agrees]),
                   check_difference=np.array([f * float(res.check_difference[-1]) + diff]),
                   points_evaluated=res.points_evaluated + points, columns=res.columns + columns)
