"""Workspaces of any mechanism with a margin: volume (area for planar ones) per branch and of
their union.

`measure_workspace(mech)` integrates the mechanism's continuous margin (> 0 inside; see
`kinematics.mechanisms.base`) with `kinematics.analyses.columns.column_volume` (exact columns,
adaptive quadrature, with an error estimate); the earlier cell-refinement estimator
`kinematics.analyses.cells.adaptive_volume` stays available (engine="cells", used by the design
sweep and the benchmark). The margins are the families' own (`Mechanism.margin`): the
3-[P2(US)]'s fused scan kernel, the SCARA's reach and joint slacks, the Delta's reach, actuator
and ball-joint slacks.

Every limit comes from the URDF (through `kinematics.mechanisms.mechanism_of`). Two independent
checks, used by the tests: `volume_monte_carlo`, uniform samples through the mechanism's inverse
kinematics (`Mechanism.ik`), and the SCARA's area by a 1D quadrature over the radius
(`kinematics.mechanisms.scara.joint_space.area_quadrature`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.analyses.cells import VolumeEstimate, adaptive_volume
from kinematics.analyses.columns import ROOT_TOL, ColumnVolume, column_volume
from kinematics.mechanisms.base import UNION, Mechanism, check_mechanism
from kinematics.sizes import MAX_POINTS, check_count, check_points


@dataclass(frozen=True)
class Workspace:
    """A measured workspace.

    Attributes:
        planes: for a planar motion whose assemblies move in different parallel planes
            (`Mechanism.parallel_planes`), the planes' names: each is a target (the union of its
            branches) before the last, and the last ("union") is their sum (the planes do not
            overlap); () otherwise.
        robot: its name. planar: area [m^2] rather than volume [m^3].
        targets: the regions measured, e.g. ("---", "union") or ("up", "down", "union").
        branch_key: the JSON key of the per-branch results: "elbows" for a planar arm's, else "modes".
        limits: "all" or "actuators".
        result: the measurement, one entry per target (ColumnVolume; VolumeEstimate for the
            "cells" engine).
        seconds: wall time of the measurement.
        measure_zero: why the set has zero measure when it has (a serial tool point with fewer
            freedoms than the task space, `SerialArm.measure_zero`): the result is then an exact 0,
            converged, with no evaluation; None otherwise.
    """

    robot: str
    planar: bool
    targets: tuple[str, ...]
    limits: str
    result: ColumnVolume | VolumeEstimate
    seconds: float
    parameters: dict[str, Any] = field(default_factory=dict)
    branch_key: str = "modes"
    planes: tuple[str, ...] = ()
    measure_zero: str | None = None

    def unconverged(self) -> dict[str, str]:
        """Targets (branches, union) whose own estimate failed, each with the reason (empty for the
        cell engine, which has no per-target verdict)."""
        r = self.result
        if not isinstance(r, ColumnVolume):
            return {}
        fixed = self.fixed_error_binds()
        bound = np.zeros_like(r.error) if r.fixed_error is None else r.fixed_error

        def why(k: int) -> str:
            if not r.check_agrees[k]:
                return "the run at half the step disagreed beyond the error estimates"
            if fixed[k]:
                return (f"a bound no finer step reduces ({bound[k]:.2g} of the error estimate) exceeds the "
                        "tolerance")
            if r.out_of_budget is not None and r.out_of_budget[k]:
                unchecked = "; no check run at half the step" if np.isnan(r.check_difference[k]) else ""
                return ("the search budget ran out (a serial arm's reach searches: a partial base turn's circles' "
                        f"integral, or its columns in 3-D{unchecked}): the estimate and its error are the answer at "
                        "this budget")
            return "error estimate above the tolerance"

        return {name: why(k) for k, name in enumerate(self.targets) if not r.target_converged[k]}

    def fixed_error_binds(self) -> np.ndarray:
        """(T,) per target: the part of its error estimate no finer step reduces
        (`ColumnVolume.fixed_error`) alone exceeds its tolerance."""
        r = self.result
        if not isinstance(r, ColumnVolume) or r.fixed_error is None:
            return np.zeros(len(self.targets), dtype=bool)
        return np.asarray(r.fixed_error > r.rtol * np.abs(r.estimate))

    @property
    def total(self) -> float:
        """The union's measure [m^3 or m^2]."""
        return float(self.result.estimate[-1])

    @property
    def error(self) -> float:
        """The union's estimated error [m^3 or m^2]."""
        return float(self.result.error[-1])

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready report with the issue's stable keys (volume_m3 / area_m2, error_estimate,
        converged, modes / elbows (`branch_key`), seconds)."""
        r = self.result
        unit = "m2" if self.planar else "m3"
        key = "area" if self.planar else "volume"
        per = {name: {key: float(r.estimate[k]), "error_estimate": float(r.error[k])}
               for k, name in enumerate(self.targets[:-1])}
        if isinstance(r, ColumnVolume):
            for k, name in enumerate(self.targets[:-1]):
                per[name]["converged"] = bool(r.target_converged[k])
        box = r.box
        out: dict[str, Any] = {
            "robot": self.robot,
            "limits": self.limits,
            f"{key}_{unit}": self.total,
            "error_estimate": self.error,
            "rtol": r.rtol,
            "converged": r.converged,
            self.branch_key: per,
            "bbox": [box[0].tolist(), box[1].tolist()],
            "points_evaluated": r.points_evaluated,
            "step_m": r.step,
            "seconds": self.seconds,
            **({"union_rule": (f"the sum of the parallel planes' areas ({', '.join(self.planes)}; they do not "
                               "overlap), each plane's area the union of its branches")} if self.planes else {}),
            "parameters": self.parameters,
            **({"measure_zero": self.measure_zero} if self.measure_zero is not None else {}),
        }
        if isinstance(r, ColumnVolume):
            out.update(method="columns", columns=r.columns)
        else:
            out.update(method="cells", **{f"bounds_{unit}": [float(r.lower[-1]), float(r.upper[-1])]},
                       finest_step_m=r.finest_step)
        return out


BRANCH_FLOOR = 1e-2
"""A branch's volume is measured to rtol of itself or of this fraction of the union, whichever is
larger: the slivers of p2us-results' other working modes with every limit (2.7e-7 to 2.8e-4 m^3
beside a 0.1325 m^3 union) cannot be pinned to their own relative tolerance (the slices' break
charges alone exceed it) and kept the engine refining for over ten minutes; with the floor the run
takes ~3 s and reports each sliver with the error estimate it has (e.g. +++: 2.72e-7 +/- 2.4e-8 m^3).
The union and any branch above 1 % of it keep their own relative tolerance."""


def _measure(margin: Callable[[np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray, step: float,
             rtol: float | None, engine: str, progress: bool, max_points: int | None, check: bool
             ) -> ColumnVolume | VolumeEstimate:
    if engine == "cells":
        kw = {} if max_points is None else {"max_points": max_points}
        return adaptive_volume(margin, lo, hi, step, rtol, progress=progress, **kw)
    if engine != "columns":
        from kinematics.errors import UnknownChoiceError

        raise UnknownChoiceError(engine, ("columns", "cells"))
    rtol = 1e-2 if rtol is None else rtol
    return column_volume(margin, lo, hi, step=step, rtol=rtol, check=check, progress=progress, floor=BRANCH_FLOOR,
                         root_tol=root_tolerance(rtol, step),
                         max_points=MAX_POINTS if max_points is None else max_points)


def root_tolerance(rtol: float, step: float) -> float:
    """Width [m] to which sampled columns bracket their roots: 1e-3 x rtol x step (at least ROOT_TOL).
    A column has a few ends, each bracket's width enters the error estimate, so the brackets add
    about 1e-3 x rtol x (ends x step / column length) of the measure: nothing beside rtol, while a
    margin that jumps at the boundary (a closed loop's) costs one evaluation per halving."""
    return max(ROOT_TOL, 1e-3 * rtol * step)


def require_volume_task(mech: Mechanism) -> None:
    """Raise unless `mech` has a margin over a 2- or 3-dimensional task space (a workspace area
    or volume needs both)."""
    mech.require("margin", "a workspace measurement")
    if mech.task_dim not in (2, 3):
        from kinematics.errors import UnsupportedRobotError

        raise UnsupportedRobotError(mech.name, f"a workspace area or volume needs a 2- or 3-dimensional task space; "
                                               f"this one is {mech.task_dim}-dimensional ({', '.join(mech.task_axes)})")


def measure_workspace(mech: Mechanism, *, step: float = 0.005, rtol: float | None = 1e-4,
                      branches: Sequence[str] | None = None, limits: str = "all", progress: bool = False,
                      max_points: int | None = None, engine: str = "columns", check: bool = False) -> Workspace:
    """Volume [m^3] (area [m^2] for a planar mechanism) of each branch's workspace and of their union.

    engine "columns" (default): `column_volume` with column sampling step `step` [m] and relative
    tolerance `rtol` on its error estimate; "cells": the cell-refinement estimator with grid step
    `step`. check: rerun at half the step and compare (columns only).
    """
    check_mechanism(mech, "measure_workspace")
    require_volume_task(mech)
    chosen = mech.check_branches(branches) if mech.branches else ()  # a serial arm: the union only
    mech.check_limits(limits)
    zero = zero_measure_workspace(mech, limits, rtol, step) if engine == "columns" else None
    if zero is not None:  # before the box, the planes and the margin, which it needs none of
        return zero
    lo, hi = mech.bounding_box(limits)
    planes = mech.parallel_planes(chosen) if engine == "columns" else ()
    margin = mech.margin(chosen, limits)
    if planes:
        margin = _plane_unions(margin, len(chosen), [idx for _, idx in planes])
    t0 = time.perf_counter()
    res = _measure(margin, lo, hi, step, rtol, engine, progress, max_points, check)
    names = tuple(name for name, _ in planes)
    if planes:
        res = _sum_planes(res, len(chosen), len(planes))  # type: ignore[arg-type]
    return Workspace(mech.name, mech.task_dim == 2, (*chosen, *names, UNION), limits, res, time.perf_counter() - t0,
                     mech.parameters(), "elbows" if mech.branch_kind == "elbow" else "modes", names)


def zero_measure_workspace(mech: Mechanism, limits: str, rtol: float | None, step: float) -> Workspace | None:
    """The workspace of a mechanism whose reachable set has zero measure (`measure_zero`: a serial
    tool point with fewer freedoms than the task space), as an exact 0, converged, with no
    evaluation (no sampling can find such a set: not a "not converged" 0); None for any other.
    Collisions only remove from it: the collision-aware measure is the same 0."""
    t0 = time.perf_counter()
    zero = getattr(mech, "measure_zero", None)
    why = zero() if zero is not None else None
    if why is None:
        return None
    d = mech.task_dim
    one = np.ones(1, bool)
    res = ColumnVolume(np.zeros(1), np.zeros(1), True, 1e-2 if rtol is None else rtol, step, step, 0, 0, np.zeros(1),
                       np.full((2, d), np.nan), one, one)
    return Workspace(mech.name, d == 2, (UNION,), limits, res, time.perf_counter() - t0, mech.parameters(),
                     measure_zero=why)


def _plane_unions(margin: Callable[[np.ndarray], np.ndarray], B: int, planes: Sequence[Sequence[int]]
                  ) -> Callable[[np.ndarray], np.ndarray]:
    """points -> (N, B + G + 1): the B branches' margins, each parallel plane's union (the max over
    its branches), then the union of all in the task coordinates (the engine's last target: its
    bounding box and the floor of the branches' tolerances)."""

    def f(points: np.ndarray) -> np.ndarray:
        m = margin(points)
        per = [m[:, list(idx)].max(axis=1, keepdims=True) for idx in planes]
        return np.concatenate([m[:, :B], *per, m[:, B:]], axis=1)

    return f


def _sum_planes(res: ColumnVolume, B: int, G: int) -> ColumnVolume:
    """The last target replaced by the sum of the G plane unions (targets B .. B + G - 1): the
    planes are parallel and distinct, so their regions do not overlap; the error estimates add."""
    import dataclasses

    planes = slice(B, B + G)

    def last(a: np.ndarray, value: Any) -> np.ndarray:
        out = np.array(a, copy=True)
        out[-1] = value
        return out

    return dataclasses.replace(
        res, estimate=last(res.estimate, res.estimate[planes].sum()), error=last(res.error, res.error[planes].sum()),
        check_difference=last(res.check_difference, res.check_difference[planes].sum()),
        target_converged=last(res.target_converged, bool(np.all(res.target_converged[planes]))),
        check_agrees=last(res.check_agrees, bool(np.all(res.check_agrees[planes]))))


def volume_monte_carlo(mech: Mechanism, n: int, rng: np.random.Generator,
                       limits: str = "all") -> tuple[float, float]:
    """The union's volume [m^3] (area [m^2] for a planar mechanism) and its standard error by
    uniform sampling of the bounding box through the mechanism's inverse kinematics
    (`Mechanism.ik`: for the closed-form families, the NumPy closed forms), independent of its
    margin and of the volume engine."""
    check_mechanism(mech, "volume_monte_carlo")
    mech.require("ik", "a Monte-Carlo volume")
    mech.check_limits(limits)
    check_count("n", n, 1, " of samples")
    n = check_points("n", float(n), hint="use fewer samples")
    lo, hi = mech.bounding_box(limits)
    p = lo + (hi - lo) * rng.random((n, mech.task_dim))
    inside = mech.ik(p, limits).within_limits.any(axis=-1)
    box = float(np.prod(hi - lo))
    frac = float(inside.mean())
    return box * frac, box * math.sqrt(frac * (1 - frac) / n)
