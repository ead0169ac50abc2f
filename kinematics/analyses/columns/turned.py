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

Integrand = Callable[[np.ndarray, float, float], tuple[np.ndarray, np.ndarray, np.ndarray, int]]
"""(profile points (N, 2) = (r, z), step [m], root tolerance [m]) -> values (N,) [m rad], their
errors (N,), signatures (N,) int, searches spent (`kinematics.mechanisms.serial.turn.TurnExtent`)."""

SPAN = 32
"""The integral's starting intervals are SPAN x step wide (the engine's sampled columns start from
8 x step, where a column's length jumps; this integrand is continuous but where a circle's
measure jumps, and the quadrature refines there on its variation bound)."""


def integrate_turn(g: Integrand, lo: np.ndarray, hi: np.ndarray, step: float, cell: float, atol: float, rtol: float,
                   root_tol: float, max_points: int, order: int = 4) -> tuple[float, float, bool, int, int]:
    """X = integral of g (sampled every `step` [m]) over the profile box [lo, hi] (2,) [m] from
    intervals `cell` [m] wide, to max(rtol |X|, atol): the value [m^3], its error estimate,
    converged, integrand evaluations and searches spent."""
    spent = [0, 0]

    def pieces(k: int) -> int:
        return max(1, math.ceil((hi[k] - lo[k]) / cell))

    def values(r: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        v, e, s, n = g(np.column_stack([r, z]), step, root_tol)
        spent[0] += len(r)
        spent[1] += n
        return v[:, None], e[:, None], s[:, None]

    # slices' errors add up to <= atol / 4 over the r range
    atol_in = 0.25 * atol / (hi[0] - lo[0])
    conv_in = [True]

    def slice_area(_: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        P = len(r)
        a, ea, c, _n = adaptive_1d(lambda p, z: values(r[p], z), np.full(P, lo[1]), np.full(P, hi[1]), 0.25 * rtol,
                                   atol_in, order=order, pieces=pieces(1), max_evals=max_points)
        conv_in[0] &= bool(c.all())
        return a, ea, (a > 0).astype(np.int64)

    q, e, conv, _ = adaptive_1d(slice_area, lo[:1], hi[:1], rtol, atol, order=order, pieces=pieces(0),
                                max_evals=max_points)
    ok = bool(conv.all()) and conv_in[0] and spent[1] <= max_points
    return float(q[0, 0]), float(e[0, 0]), ok, spent[0], spent[1]


def add_turn(res: Any, turn: Any, lo: np.ndarray, hi: np.ndarray, step: float, check: bool, max_points: int,
             root_tol: float) -> Any:
    """The partial turn's volume from the full turn's `res` (a `ColumnVolume` of one target, the
    solid |W_P|): (L / 2 pi) |W_P| + X, the error (L / 2 pi) res.error + X's; with `check`, X also at
    half the step through `turn.for_check()`, their difference in the error and their agreement in
    `converged`. `turn`: `.range` L [rad] and the integrand (`Integrand`)."""
    f = turn.range / (2 * math.pi)
    base = f * float(res.estimate[-1])
    # X's share of the tolerance: a quarter of the volume's (|W| >= f |W_P|)
    atol = 0.25 * res.rtol * max(base, 1e-300)
    x1, e1, c1, n1, s1 = integrate_turn(turn, lo, hi, step, SPAN * step, atol, res.rtol, root_tol, max_points)
    x, err, conv, agrees, diff = x1, e1, c1, True, math.nan
    points = s1
    if check:
        x2, e2, c2, _n2, s2 = integrate_turn(turn.for_check(), lo, hi, step / 2, SPAN * step, atol, res.rtol, root_tol, max_points)
        diff = abs(x1 - x2)
        agrees = diff <= e1 + e2
        x, err, conv, points = x2, max(e2, diff), c1 and c2, s1 + s2
    estimate = np.array([base + x])
    error = np.array([f * float(res.error[-1]) + err])
    ok = bool(res.target_converged[-1]) and conv and agrees and bool(error[0] <= res.rtol * estimate[0] * (1 + 1e-12))
    return replace(res, estimate=estimate, error=error, converged=bool(res.converged) and ok,
                   target_converged=np.array([ok]), check_agrees=np.array([bool(res.check_agrees[-1]) and agrees]),
                   check_difference=np.array([f * float(res.check_difference[-1]) + diff]),
                   points_evaluated=res.points_evaluated + points)
