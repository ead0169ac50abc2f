"""`column_volume`: the measure of {margin >= 0} per target by exact or sampled columns, with the
check runs at halved steps (see the package docstring)."""

from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

import numpy as np

from kinematics.errors import InvalidInputError, KinematicsWarning
from kinematics.sizes import MAX_POINTS, check_count

from .quadrature import adaptive_1d, piecewise_1d
from .sampled import ROOT_TOL, Counter, column_lengths

MIN_NODES = 16
"""Exact columns: fewest starting nodes per quadrature direction (32 in the check run), whatever the
step: a step wider than the box would otherwise start both runs from the same few nodes."""

CHECK_HALVINGS = 3
"""`check`: the most times the step is halved (s/2, s/4, s/8) while successive runs disagree (or the
last target's difference exceeds its tolerance)."""

RTOL_FLOOR = 1e-9
"""Tightest relative tolerance accepted: 1000 x the root brackets over a metre-sized box, so
neither the brackets nor double-precision sums of ~1e6 columns (~1e-10) dominate the estimate."""

CHECK_SEARCHES = 2
"""Sampled columns of a margin with a `search_budget`: each check run may spend this many times
the first run's budget (twice the samples per column; as `turned.CHECK_BUDGET`)."""

START_SHARE = 0.5
"""Sampled 3D columns on a search budget: the starting grid (3 x order columns per starting
interval in each direction across the columns, each sampled every `step`) may cost at most this
share of the run's budget; a dearer one starts from wider intervals (`start_cell`), the
refinement then spending the rest where the error is. Without it a 1 cm start over the wedge
arm's 1.7 m reach box cost ~9e6 searches before the budget was first looked at."""

OUTER_SPAN = 6
"""Exact columns: the volume's outer integral starts from intervals of this many node spacings;
the 12 slices of each (the whole interval's 4-node rule and its halves') then leave no gap wider
than ~0.99 node spacing, the inner direction's (4 spacings: 0.66, at 1.5x the slices)."""


ExactColumnsFn = Callable[[np.ndarray, int, float, float],
                          tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
"""(base (M, 2), axis, z0, z1) -> lengths (M, T), errors (M, T), interval ends (M, T), signatures
(M,) int64, inside extent of the last target (M, 2): a margin's exact columns
(`kinematics.mechanisms.p2us.exact.ExactColumns`)."""


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
        check_difference: (T,) |this run - the check run| (NaN without check, or when the first
            run stopped on its search budget: no check run then).
        box: (2, d) [min, max] of the inside points found for the last target (NaN if none).
        target_converged: (T,) per target: its error estimate is within its tolerance and, with
            check, the two runs agree on it within their estimates (`converged` also needs the
            budget to last and the last target to be non-empty).
        check_agrees: (T,) per target: the two runs agree within their estimates (True without check).
        root_tol: sampled columns: the width [m] every root was bracketed to.
        fixed_error: (T,) the part of `error` that no finer step reduces, or None (a partial base
            turn's cover bound sets it, `turned.cover_bound`, only where it meets the tolerance).
        out_of_budget: (T,) the target stopped on a search budget rather than on its tolerance (a
            partial base turn's circles' integral, `turned.SEARCHES`; a margin's `search_budget`
            on sampled 3D columns), or None.
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
    fixed_error: np.ndarray | None = None
    out_of_budget: np.ndarray | None = None


def _within(estimate: np.ndarray, error: np.ndarray, rtol: float, floor: float) -> np.ndarray:
    """(T,) each target's error within its tolerance: rtol x its measure, or x floor x the last's."""
    tol = np.maximum(rtol * np.abs(estimate), rtol * floor * abs(float(estimate[-1])))
    return np.asarray(error <= tol * (1.0 + 1e-12))


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

    Three optional attributes of the margin change the run: `search_budget` (an int: each of its
    evaluations is a search with restarts, e.g. a serial arm's reach in 3D; sampled 3D columns
    then stop on that many evaluations, each check run on CHECK_SEARCHES x as many, instead of on
    `max_points`, `out_of_budget` saying so; their start costs at most START_SHARE of it, from
    intervals wider than 8 x step if need be, `start_cell`, so a feature between its wider nodes
    is seen only where the refinement goes; a first run that stops on it is returned
    unchecked), `profile` (3D margins of a solid of
    revolution: `margin`, `lo`, `hi`, `axis`, `weight` and `world_box` of its (rho, z) profile,
    measured instead with the weight 2 pi rho, Pappus; with a `turn`, a partial turn's, by
    `turned.add_turn`) and `for_check()` (the margin the check run
    uses, e.g. a search with more restarts, so that the check also compares two searches).
    """
    profile = getattr(margin, "profile", None)
    if profile is not None and np.asarray(lo).shape == (3,):
        res = column_volume(profile.margin, profile.lo, profile.hi, step=step, rtol=rtol, order=order,
                            pieces=pieces, axis=profile.axis, check=check, max_points=max_points, progress=progress,
                            floor=floor, root_tol=root_tol, weight=profile.weight)
        res = replace(res, box=profile.world_box(res.box))
        turn = getattr(profile, "turn", None)
        if turn is not None:  # a partial turn: (L / 2 pi) x the solid + the circles' integral
            from .turned import add_turn

            res = add_turn(res, turn, profile.lo, profile.hi, step, check, max_points, root_tol)
        return res
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
    check_count("order", order, 1, " of Gauss-Legendre nodes")
    if pieces is not None:
        check_count("pieces", pieces, 0, note=" (0 or None: from the step)")
    if axis is not None and not (isinstance(axis, numbers.Integral) and -d <= axis < d):
        raise InvalidInputError("axis", f"must be one of the box's axes 0..{d - 1} (or -{d}..-1), got {axis!r}")
    ax = int(np.argmin(hi - lo)) if axis is None else axis % d
    start = start_cost(step, hi - lo, ax, order, 8 * step, pieces)
    if start > max_points:
        raise InvalidInputError("step", f"{step:g} m needs {start:,} points to start, over the {max_points:,} limit; "
                                        "use a larger step")
    if _exact_of(margin, d) is not None:
        if weight is not None:
            raise InvalidInputError("weight", "exact columns take no weight")
        run: Callable[..., ColumnVolume] = _run_exact
    else:
        searches = getattr(margin, "search_budget", None) if d == 3 else None
        run = partial(_run_sampled, weight=weight, root_tol=root_tol, searches=searches)
    first = run(margin, lo, hi, step, rtol, order, pieces, ax, max_points, progress, floor=floor)
    if not check or (first.out_of_budget is not None and bool(first.out_of_budget.any())):
        # a run stopped on its search budget is not converged whatever a check says, and its
        # error (the unrefined intervals', 2-4 % relative on the wedge arm and talos's arm at the
        # CLI's defaults) dwarfs what a check finds (a second search at half the step: 6e-4 and
        # 3e-3 of the error on budgets of 1e6); its time (CHECK_SEARCHES x the budget) buys nothing
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
        more = {} if searches is None else {"searches": CHECK_SEARCHES * searches}
        return run(margin, lo, hi, step / 2**level, rtol, order, pieces, ax, max_points, progress, floor=floor,
                   **more)

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
        spent_out = second.out_of_budget is not None and bool(second.out_of_budget.any())
        if settled or spent_out or level == CHECK_HALVINGS or points + 2 * second.points_evaluated > max_points:
            break
        first = second
    error = np.maximum(second.error, diff)
    # every target's own verdict: the runs agree, and the reported error (which includes their
    # difference) is within the tolerance
    per_target = agrees & _within(first.estimate, first.error, rtol, floor) & _within(second.estimate, error, rtol, floor)
    budgets = [r.out_of_budget for r in (first, second) if r.out_of_budget is not None]
    return ColumnVolume(
        estimate=second.estimate, error=error,
        converged=first.converged and second.converged and bool(per_target.all()), rtol=rtol, step=second.step,
        cell=second.cell, columns=columns, points_evaluated=points,
        check_difference=diff,
        box=np.stack([np.fmin(first.box[0], second.box[0]), np.fmax(first.box[1], second.box[1])]),
        target_converged=per_target, check_agrees=agrees, root_tol=second.root_tol,
        out_of_budget=np.logical_or.reduce(budgets) & ~per_target if budgets else None,
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
    counter = Counter(d)
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
         weight: Callable[[np.ndarray], np.ndarray] | None = None, searches: int | None = None) -> ColumnVolume:
    """Sampled columns, nested `adaptive_1d`: with `searches` (3D) both rules price their rounds in
    margin evaluations (`adaptive_1d`'s `cost`) and stop on that many (the slices' inner rules
    may finish a round begun, up to twice it in all), not converged, `out_of_budget` set."""
    d = lo.shape[0]
    ax = int(np.argmin(hi - lo)) if axis is None else axis % d
    others = [k for k in range(d) if k != ax]
    counter = Counter(d)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(desc="volume", unit="col", unit_scale=True, delay=1.0, leave=False)

    cell = 8 * step if searches is None or d != 3 or pieces else start_cell(
        step, hi - lo, ax, order, int(START_SHARE * searches))
    if cell > 8 * step:  # said at the start: such a run ends on its budget minutes later, its error wide
        warnings.warn(KinematicsWarning(
            f"a {step:g} m step over this {' x '.join(f'{x:.3g}' for x in hi - lo)} m box needs "
            f"{start_cost(step, hi - lo, ax, order, 8 * step):,} searches to start, over {START_SHARE:.0%} of the "
            f"budget of {searches:,}: starting from {cell:.3g} m intervals instead of {8 * step:g} m, the "
            "measurement will likely stop on its search budget, not converged (a larger step or rtol needs fewer)"),
            stacklevel=2)

    def n_pieces(k: int) -> int:
        return pieces or max(1, math.ceil((hi[k] - lo[k]) / cell))

    def columns(base: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ell, err, ends = column_lengths(margin, base, lo[ax], hi[ax], step, ax, counter, root_tol)
        if weight is not None:
            w = np.asarray(weight(base), dtype=float)
            if w.shape != (len(base),) or not np.all(np.isfinite(w)):  # as check_margin for the margin
                raise InvalidInputError("weight", f"must return {len(base)} finite factors (one per column), got "
                                                  f"shape {w.shape}{'' if np.all(np.isfinite(w)) else ' with NaN or inf'}")
            w = w[:, None]
            ell, err = ell * w, err * w
        if bar is not None:
            bar.update(len(base))
        return ell, err, ends

    budget = max(1, max_points // max(1, math.ceil((hi[ax] - lo[ax]) / step) + 1))
    inner_rtol = 0.25 * rtol  # the slices' errors add up to <= rtol / 4 of the volume
    if d == 2:
        q, e, conv, _ = adaptive_1d(lambda p, x: columns(x[:, None]), lo[others[:1]], hi[others[:1]], rtol, 0.0,
                                    order=order, pieces=n_pieces(others[0]), max_evals=budget, floor=floor, ends=True)
    else:
        k_out, k_in = others
        all_conv = [True]
        # slices below this area [m^2] need no relative accuracy: the volume's tolerance covers them
        atol_in = 1e-3 * rtol * (hi[k_in] - lo[k_in]) * step

        def slice_area(_: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            P = len(x)

            def inner(p: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                return columns(np.stack([x[p], y], axis=1))

            before = counter.points
            # the slices' rules in searches: what is left of twice the budget (a slice cut short
            # carries its first rules' errors into the volume's, so it may overrun the outer's)
            priced = {} if searches is None else {"max_evals": max(1, 2 * searches - before),
                                                  "cost": lambda: counter.points - before}
            a, ea, c, _evals = adaptive_1d(inner, np.full(P, lo[k_in]), np.full(P, hi[k_in]), inner_rtol, atol_in,
                                      order=order, pieces=n_pieces(k_in), **({"max_evals": budget} | priced),
                                      floor=floor, ends=True)
            all_conv[0] &= bool(c.all())
            return a, ea, (a > 0).astype(np.int64)

        outer = {"max_evals": budget} if searches is None else {"max_evals": searches,
                                                                "cost": lambda: counter.points}
        q, e, conv, _ = adaptive_1d(slice_area, lo[[k_out]], hi[[k_out]], rtol, 0.0, order=order,
                                    pieces=n_pieces(k_out), floor=floor, **outer, ends=True)
        conv = conv & all_conv[0]
    if bar is not None:
        bar.close()
    box = np.stack([counter.lo, counter.hi])
    within = _within(q[0], e[0], rtol, floor)
    # with a search budget the rules stop unconverged only on it (or on a slice cut short by it)
    spent_out = None if searches is None or d != 3 else ~within
    in_budget = spent_out is not None or counter.columns <= budget  # (searches: the rules kept to them)
    return ColumnVolume(
        # finding nothing cannot be told from sampling past everything: never a confident 0
        estimate=q[0], error=e[0], converged=bool(np.all(conv)) and in_budget and bool(q[0, -1] > 0),
        rtol=rtol,
        step=step, cell=cell, columns=counter.columns,
        points_evaluated=counter.points, check_difference=np.full(q.shape[1], np.nan),
        box=np.where(np.isfinite(box), box, np.nan),
        target_converged=within, check_agrees=np.ones(q.shape[1], bool), root_tol=root_tol,
        out_of_budget=spent_out,
    )


def start_cell(step: float, span: np.ndarray, axis: int, order: int, budget: int) -> float:
    """The sampled 3D columns' starting interval [m]: 8 x step, or wider until the starting grid,
    (3 order ceil(span_i / cell)) (3 order ceil(span_j / cell)) columns of span_axis / step + 1
    samples each (i, j the directions across the columns), costs at most `budget` margin
    evaluations (the roots' refinement not counted: a few per column), or one interval spans
    each direction."""
    cell = 8 * step
    while start_cost(step, span, axis, order, cell) > budget and cell < max(np.delete(span, axis)):
        cell *= 1.05  # (at most ~60 steps from a 1 cm step to a metre-sized box)
    return cell


def start_cost(step: float, span: np.ndarray, axis: int, order: int, cell: float, pieces: int | None = None) -> int:
    """Margin samples of the columns' starting grid: per direction across the columns, `pieces`
    (or span / cell rounded up) starting intervals of 3 x order columns (the Gauss rule on each and
    on its halves), every column sampled every `step` along `axis`."""
    per_column = math.ceil(span[axis] / step) + 1
    return per_column * math.prod(3 * order * (pieces or max(1, math.ceil(span[k] / cell)))
                                  for k in range(len(span)) if k != axis)
