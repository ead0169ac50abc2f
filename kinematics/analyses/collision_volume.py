"""The volume (area) of a collision-free workspace: each branch's and the union's, with the
kinematic union and the volume each binding pair removes, measured in one column run.

The margin is `kinematics.analyses.collisions`' (m_b = min(k_b, min over pairs of d_p)). For the
closed-form families (p2us, delta) the column engine integrates it by collision-free exact
columns (`kinematics.analyses.collision_columns`: the kinematic intervals exact, the collision
ends found inside them); for any other mechanism `column_volume`'s sampled columns do, with the
error estimate they give any margin (same caveats: a feature thinner than the column step can be
missed; the check run at half the step looks for it). A serial arm's margin is
`kinematics.analyses.serial_collisions`'.

A pre-scan on a grid (`kinematics.analyses.collision_prescan`) finds the pairs with a negative
distance somewhere inside the kinematic workspace and the cells where some pair comes near
contact. Where none does, the measurement is the kinematic one, by the mechanism's exact columns
where it has them (the Delta: no pair comes near contact); otherwise the distances are evaluated
in the close cells only (m_b = k_b elsewhere). Each binding pair (at most `MAX_WATCHED`, most
often negative first) gets its own target, the union with that pair alone, so the volume it
removes alone is measured in the same run, as is the kinematic union (the volume the collisions
remove in all).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.analyses.collision_prescan import Prescan
from kinematics.analyses.collisions import CollisionMargin, collision_model_of, summary
from kinematics.analyses.columns import ColumnVolume, column_volume
from kinematics.analyses.workspace import (
    BRANCH_FLOOR,
    Workspace,
    require_volume_task,
    root_tolerance,
    zero_measure_workspace,
)
from kinematics.generic.capsules import AnalyticDistances
from kinematics.generic.collision import CollisionModel
from kinematics.generic.obstacles import Obstacles
from kinematics.mechanisms.base import UNION, Mechanism, check_mechanism
from kinematics.sizes import MAX_POINTS

if TYPE_CHECKING:
    from kinematics.analyses.serial_collisions import Turn
    from kinematics.generic.turn_envelope import TurnEnvelope

SERIAL_PRESCAN_CELLS = 24
"""Grid points per axis of a serial arm's pre-scan in 3-D (each point runs the reach search and,
inside, every pair's distance: 24^3 points against 48^2 on a revolved arm's profile)."""

MAX_WATCHED = 8
"""Binding pairs measured one by one (each adds a target to the volume run)."""

PRESCAN_CELLS = 48
"""Grid points per axis of the pre-scan (a coarser grid clears fewer cells: its threshold grows
with the cell diagonal)."""


@dataclass(frozen=True)
class PairRemoval:
    """Volume [m^3] (area [m^2]) a binding pair removes from the kinematic union when it alone is
    checked, with its error estimate (the two measures' estimates added). The pair is one of the
    checked model's (with a turn envelope, all its bands together: `TurnEnvelope.original`)."""

    links: tuple[str, str]
    geometries: tuple[str, str]
    removed: float
    error: float
    prescan_points: int


@dataclass(frozen=True)
class CollisionWorkspace:
    """A collision-aware workspace: `workspace` (per branch and union, collisions excluded), the
    kinematic union measured in the same run, what each watched pair removes alone, and the
    binding pairs found but not measured alone (beyond `MAX_WATCHED`)."""

    workspace: Workspace
    kinematic: float
    kinematic_error: float
    pairs: tuple[PairRemoval, ...]
    unmeasured: tuple[tuple[str, str], ...]
    collision: dict[str, Any]

    @property
    def removed(self) -> float:
        """Volume the collisions remove in all [m^3 or m^2]."""
        return self.kinematic - self.workspace.total

    def as_dict(self) -> dict[str, Any]:
        out = self.workspace.as_dict()
        out["collisions"] = {
            "kinematic_volume": self.kinematic, "kinematic_error_estimate": self.kinematic_error,
            "removed": self.removed, "removed_error_estimate": self.kinematic_error + self.workspace.error,
            "binding_pairs": [{"links": list(p.links), "geometries": list(p.geometries), "removed": p.removed,
                               "error_estimate": p.error, "prescan_points": p.prescan_points} for p in self.pairs],
            "binding_not_measured_alone": [list(p) for p in self.unmeasured],
            **self.collision,
        }
        return out


def _binding(scan: Prescan, watch: int) -> tuple[list[tuple[int, int]], list[int]]:
    """The pairs negative somewhere in the pre-scan, most often first, with their counts, and the
    first `watch` of them (measured alone)."""
    order = np.argsort(-scan.counts, kind="stable")
    found = [(int(k), int(scan.counts[k])) for k in order if scan.counts[k] > 0]
    return found, [k for k, _ in found[:watch]]


def _take(r: ColumnVolume, idx: list[int]) -> ColumnVolume:
    """The targets `idx` of a column measurement."""
    return dataclasses.replace(r, estimate=r.estimate[idx], error=r.error[idx], check_difference=r.check_difference[idx],
                               target_converged=r.target_converged[idx], check_agrees=r.check_agrees[idx])


def _serial_route(mech: Mechanism, robot: Any, cm: CollisionModel, dist: AnalyticDistances, lo: np.ndarray,
                  hi: np.ndarray, watch: int, turn: Turn) -> tuple[Any, Prescan, list[tuple[int, int]], list[int],
                                                                   TurnEnvelope | None, dict[str, Any]]:
    """A serial arm's margin (`serial_collisions.serial_margin`), its pre-scan (of the profile
    where it has one), the binding pairs, the watched ones, the turn envelope used and the report's
    `search` and `turn` entries. The pairs are `cm`'s: with a turn envelope, a pair of an enveloped
    body is its band pairs together (`TurnEnvelope.original`), the smallest of their distances."""
    from kinematics.analyses.serial_collisions import serial_margin

    plain, env = serial_margin(mech, robot, cm, dist, turn)
    on, shape = plain.profile_margin, plain.profile  # a solid of revolution: its profile is scanned
    pair_of = None if env is None else env.original
    scan = (Prescan(plain, lo, hi, SERIAL_PRESCAN_CELLS, pair_of) if on is None or shape is None
            else Prescan(on, shape.lo, shape.hi, PRESCAN_CELLS, pair_of))
    found, watched = _binding(scan, watch)
    columns = watched if env is None else [np.flatnonzero(env.original == k) for k in watched]
    r = plain.reach
    route = "envelope" if env is not None else "profile" if shape is not None else r.setup.mode
    extra = {"search": {"mode": r.setup.mode, "samples": r.samples, "restarts": r.restarts},
             "turn": {"route": route}}
    return plain.with_prescan(columns, scan), scan, found, watched, env, extra


def measure_collision_workspace(mech: Mechanism, robot: Any, *, step: float = 0.005, rtol: float | None = 1e-3,
                                branches: Sequence[str] | None = None, limits: str = "all",
                                progress: bool = False, check: bool = True,
                                collision_model: CollisionModel | None = None,
                                box: tuple[np.ndarray, np.ndarray] | None = None,
                                max_points: int | None = None, watch: int = MAX_WATCHED,
                                obstacles: Obstacles | None = None, self_collisions: bool = True,
                                exact: bool = True, turn: Turn = "auto") -> CollisionWorkspace:
    """Volume (area) of each branch's collision-free workspace and of their union, with the
    kinematic union and each binding pair's removal measured in the same column run.

    A pre-scan (`kinematics.analyses.collision_prescan.Prescan`) finds the pairs that bind and the
    cells where some pair comes near contact; where none does, the measurement is the kinematic
    one (the mechanism's exact columns where it has them), else one run of the joined margin
    (`CollisionMargin`, distances evaluated in the close cells only): by collision-free exact
    columns for the closed-form families (`collision_columns.ExactCollisionMargin`), else by
    sampled columns.

    Args:
        collision_model: the pairs to check (default: `CollisionModel.from_robot(robot)`: the
            URDF's collision shapes less adjacent, touching-at-reference and sidecar-disabled pairs).
        box: (lo, hi) [m] to measure within instead of the mechanism's bounding box (the part of
            the workspace inside it).
        watch: how many binding pairs get their own target (each costs its roots' refinement).
        obstacles: fixed bodies the robot must not touch (`load_obstacles`), with the default model.
        self_collisions: with the default model, check the robot's own pairs (False: obstacles only).
        exact: use the collision-free exact columns where the mechanism has exact columns (False:
            sampled columns, the route of any other mechanism).
        turn: a serial arm with a full-turn base and pairs its turn changes (a fixed body against
            a carried one, `serial_collisions.Turn`): "auto" measures the profile with each fixed
            body's turn envelope (a lower bound) and without its pairs (an upper bound) in one run,
            each to rtol / 2, and reports their midpoint, its error the half-width plus the larger
            error estimate; where the bracket's width estimated on the pre-scan's grid
            (`bracket_estimate`), or the error after the run, exceeds rtol x the volume, it
            measures in 3-D instead. "envelope" keeps the bracket (then not converged), "spatial"
            measures in 3-D.
    """
    check_mechanism(mech, "measure_collision_workspace")
    require_volume_task(mech)
    chosen = mech.check_branches(branches)
    mech.check_limits(limits)
    cm = collision_model if collision_model is not None else collision_model_of(robot, obstacles, self_collisions)
    dist = AnalyticDistances(cm)
    zero = zero_measure_workspace(mech, limits, rtol, step)
    if zero is not None:  # nothing to remove from: the same exact 0 as the kinematic measure
        return CollisionWorkspace(zero, 0.0, 0.0, (), (), {**summary(cm, dist), "pairs_that_can_bind": 0})
    lo, hi = mech.bounding_box(limits) if box is None else (np.asarray(box[0], float), np.asarray(box[1], float))
    t0 = time.perf_counter()
    margin: Any
    extra: dict[str, Any] = {}
    env = None

    def in_3d(why: dict[str, Any]) -> CollisionWorkspace:
        """The serial arm measured in 3-D, its report saying why (a turn envelope's bracket too wide)."""
        again = measure_collision_workspace(
            mech, robot, step=step, rtol=rtol, branches=branches, limits=limits, progress=progress, check=check,
            collision_model=cm, box=box, max_points=max_points, watch=watch, turn="spatial")
        again.collision["turn"] = {**why, "route": "spatial"}
        return again

    if "reach_search" in mech.capabilities:  # the reach search's configurations (`analyses.serial_collisions`)
        margin, scan, found, watched, env, extra = _serial_route(mech, robot, cm, dist, lo, hi, watch, turn)
        if env is not None and turn == "auto":  # a bracket wider than the tolerance on a grid: in 3-D at once
            from kinematics.analyses.serial_collisions import bracket_estimate

            width, upper = bracket_estimate(margin, PRESCAN_CELLS)
            if width > (1e-2 if rtol is None else rtol) * upper:
                return in_3d({"estimated_half_width": 0.5 * width, "why": (
                    "the turn envelope's bracket, estimated on the pre-scan's grid, is wider than the tolerance")})
    else:
        scan = Prescan(CollisionMargin(mech, robot, dist, chosen, limits), lo, hi, PRESCAN_CELLS)
        found, watched = _binding(scan, watch)
        margin = CollisionMargin(mech, robot, dist, chosen, limits, watched, prescan=scan)
    rtol = 1e-2 if rtol is None else rtol
    budget = MAX_POINTS if max_points is None else max_points
    B, W = len(chosen), len(watched)
    run = partial(column_volume, lo=lo, hi=hi, step=step, rtol=rtol, check=check, progress=progress,
                  floor=BRANCH_FLOOR, root_tol=root_tolerance(rtol, step), max_points=budget)
    if not scan.near.any() and not found:  # no pair comes near contact: the kinematic measure (exact columns if any)
        res = run(margin.kinematic)
        kin, kin_err, removals = float(res.estimate[B]), float(res.error[B]), []
        if env is not None:  # no pair near contact: the kinematic profile
            env, extra["turn"] = None, {"route": "profile"}
    else:
        if exact:
            from kinematics.analyses.collision_columns import SPACING, ExactCollisionMargin, has_exact_columns

            if has_exact_columns(margin):
                margin = ExactCollisionMargin(margin, scan, SPACING * step, root_tolerance(rtol, step))
        # with a turn envelope, each bound to half the tolerance: the bracket's half-width takes the rest
        res = run(margin, rtol=rtol / 2 if env is not None else rtol)
        kin, kin_err = float(res.estimate[B]), float(res.error[B])
        removals = [(kin - float(res.estimate[B + 1 + n]), kin_err + float(res.error[B + 1 + n])) for n in range(W)]
        if env is not None:
            from kinematics.analyses.serial_collisions import bracket

            res, bounds = bracket(res, B, B + 2 + W, B + 1 + W, rtol)
            extra["turn"] = {**bounds, "enveloped_pairs_checked": len(env.model.pairs), "enveloped": [
                {"link": link, "geometry": name, "bands": [{"from_m": b.lo, "to_m": b.hi, "radius_m": b.radius}
                                                           for b in bands]} for link, name, bands in env.enveloped]}
            if not res.target_converged[-1] and turn == "auto":  # the bracket is too wide: in 3-D
                return in_3d({**extra["turn"], "why": "the envelope's bracket did not meet the tolerance"})
        else:
            res = _take(res, [*range(B), B + 1 + W])
    ws = Workspace(mech.name, mech.task_dim == 2, (*chosen, UNION), limits, res,
                   time.perf_counter() - t0, mech.parameters(), "elbows" if mech.branch_kind == "elbow" else "modes")
    pairs = tuple(PairRemoval(cm.pair_links[k], cm.pair_names[k], removed, error, count)
                  for (k, count), (removed, error) in zip(found[:watch], removals, strict=True))
    return CollisionWorkspace(ws, kin, kin_err, pairs, tuple(cm.pair_links[k] for k, _ in found[watch:]),
                              {**summary(cm, dist), "pairs_that_can_bind": int(scan.active.sum()), **extra})
