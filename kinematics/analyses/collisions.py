"""Collision-free workspaces: the self-collision (and obstacle) margin joins the joint limits.

Per branch b the margin at a task point x is

    m_b(x) = min(k_b(x), min over pairs p of d_p(q_b(x))),

k_b the mechanism's kinematic margin (reach and joint limits, > 0 inside), q_b(x) the whole tree's
configuration there (loops closed) and d_p the signed distance of collision pair p [m]
(`kinematics.generic.capsules`: closed forms for capsules, spheres and plates, coal for the rest;
a capsule beside a plate but clear of its slab keeps the slab's distance, a positive lower bound,
so every term has the true distance's sign and the min's zero set is the true one).
Where k_b <= 0 the point is outside whatever the distances, so m_b = k_b there (no configuration
exists); this keeps the sign of the min everywhere, and every sign change of m_b is one of the
min's. The union's margin is max_b m_b. For the closed-form families (p2us, delta) the column
engine integrates them by collision-free exact columns (`kinematics.analyses.collision_columns`:
the kinematic intervals exact, the collision ends found inside them); for any other mechanism
`column_volume`'s sampled columns do, with the error estimate they give any margin (same caveats:
a feature thinner than the column step can be missed; the check run at half the step looks for
it).

A pre-scan on a grid (`kinematics.analyses.collision_prescan`) finds the pairs with a negative
distance somewhere inside the kinematic workspace and the cells where some pair comes near
contact. Where none does, the measurement is the kinematic one, by the mechanism's exact columns
where it has them (the Delta: no pair comes near contact); otherwise the distances are evaluated
in the close cells only (m_b = k_b elsewhere). Each binding pair (at most `MAX_WATCHED`, most
often negative first) gets its own target, the union with that pair alone, so the volume it
removes alone is measured in the same run, as is the kinematic union (the volume the collisions
remove in all).

Obstacles (`kinematics.generic.obstacles`) add pairs (robot body, obstacle) to the same margin;
with `self_collisions=False` they are the only pairs.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.analyses.collision_prescan import Prescan
from kinematics.analyses.columns import ColumnVolume, column_volume
from kinematics.analyses.workspace import BRANCH_FLOOR, Workspace, root_tolerance
from kinematics.errors import InvalidInputError, MissingCapabilityError
from kinematics.generic.capsules import COAL, AnalyticDistances
from kinematics.generic.collision import CollisionModel
from kinematics.generic.obstacles import Obstacles
from kinematics.mechanisms.base import UNION, Mechanism
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


def collision_model_of(robot: Any, obstacles: Obstacles | None = None, self_collisions: bool = True
                       ) -> CollisionModel:
    """The pairs to check: the robot's own (`self_collisions`) and each moving body against each
    obstacle. Raises `InvalidInputError` if obstacles are given and no body can touch them."""
    if obstacles is None and not self_collisions:
        raise InvalidInputError("obstacles", "nothing to check: give obstacles or self-collisions")
    cm = CollisionModel.from_robot(robot, obstacles=obstacles, self_collisions=self_collisions)
    if obstacles is not None and not any(a in cm.obstacles or b in cm.obstacles for a, b in cm.pairs):
        raise InvalidInputError("obstacles", f"{robot.name} has no collision shape on a moving body: "
                                             "nothing can touch the obstacles")
    return cm


def collision_refusal(mech: Mechanism) -> tuple[str, str] | None:
    """(option, reason) where a collision-aware volume of `mech` cannot be had, else None: the
    margin needs configurations at task points (`ik`, or a serial arm's reach search)."""
    serial = "reach_search" in mech.capabilities
    if "ik" not in mech.capabilities and not serial:
        return ("--collisions/--obstacles", (f"{mech.family}: no configurations at task points to check; p2us, "
                                             "delta, the planar arm, closed loops and serial arms are collision-aware"))
    return None


def design_options(robot: Any, self_collisions: bool, obstacles: str | None) -> dict[str, Any]:
    """Collision options for designs derived from `robot` (a p2us or delta; plain data, for Dask
    tasks): the collision sizes its sidecar records (the generator's defaults where absent), the
    self-collision switch and the obstacle file's absolute path (read once here, so a bad file
    fails before any design)."""
    import dataclasses

    from kinematics.generic.obstacles import load_obstacles
    from kinematics.mechanisms.three_limb.urdf import read_collision_sizes
    from kinematics.model.loops import sidecar_for

    if obstacles:
        load_obstacles(obstacles)
    sizes = read_collision_sizes(sidecar_for(Path(robot.urdf_path)), _generator(_family(robot)).SIZES)
    return {"sizes": dataclasses.asdict(sizes), "self": self_collisions,
            "obstacles": str(Path(obstacles).resolve()) if obstacles else None}


def design_checks(family: str, params: Any, options: dict[str, Any]) -> tuple[Any, CollisionModel]:
    """A design's robot, generated (in a temporary folder) from `params` with the collision sizes
    of `options` (`design_options`), and its collision model."""
    import tempfile

    from kinematics.generic.obstacles import load_obstacles
    from kinematics.mechanisms.three_limb.urdf import CollisionSizes
    from kinematics.model.robot import load_robot

    obstacles = load_obstacles(options["obstacles"]) if options.get("obstacles") else None
    with tempfile.TemporaryDirectory() as tmp:
        urdf, _ = _generator(family).write(params, Path(tmp) / "design.urdf", sizes=CollisionSizes(**options["sizes"]))
        robot = load_robot(urdf)
        return robot, collision_model_of(robot, obstacles, self_collisions=bool(options.get("self", True)))


def _family(robot: Any) -> str:
    from kinematics.mechanisms import mechanism_of

    return mechanism_of(robot).family


def _generator(family: str) -> Any:
    """The URDF generator module of a three-limb family."""
    if family == "p2us":
        from kinematics.mechanisms.p2us import urdf as p2us_urdf

        return p2us_urdf
    if family == "delta":
        from kinematics.mechanisms.delta import urdf as delta_urdf

        return delta_urdf
    from kinematics.errors import UnsupportedRobotError

    raise UnsupportedRobotError(family, "collision checks of generated designs support p2us and delta")


def configurations(mech: Mechanism, robot: Any, points: np.ndarray, branch: str) -> np.ndarray:
    """The tree's configurations (N, nq) with the task point at `points` (N, d) [m] in `branch`:
    vectorised for the three-limb families, from the branch's IK for an open chain (its actuators
    are all its joints), else `mech.joint_values` point by point."""
    if mech.family in ("p2us", "delta"):
        from kinematics.mechanisms.delta import urdf as delta_urdf
        from kinematics.mechanisms.p2us import urdf as p2us_urdf

        module: Any = p2us_urdf if mech.family == "p2us" else delta_urdf
        return module.configurations_at(mech.params, robot.model, points, branch)
    import pinocchio as pin

    model = robot.model
    out = np.tile(pin.neutral(model), (len(points), 1))
    if not mech.closed_loop and "ik" in mech.capabilities:
        q = mech.ik(points).q[:, mech.branches.index(branch)]
        if q.shape[1] != robot.nv or not np.isfinite(q).all():  # as `robot.configuration` would
            for row in q:
                robot.joint_values(row)
        for k, d in enumerate(robot.dofs):  # `robot.configuration`, a column at a time
            if d.kind == "continuous":
                out[:, d.idx_q], out[:, d.idx_q + 1] = np.cos(q[:, k]), np.sin(q[:, k])
            else:
                out[:, d.idx_q] = q[:, k]
        return out
    mech.require("joint_values", "collision checks at task points")
    for n, p in enumerate(points):
        values = mech.joint_values(p, branch)
        out[n] = robot.configuration([values[name] for name in robot.joint_names])
    return out


class CollisionMargin:
    """The collision-aware margin (module docstring) of `branches` under `limits`, as a column
    engine margin: points (N, d) -> (N, B + 2 + W) columns: each branch's m_b, the kinematic
    union max_b k_b, the union with each watched pair alone, then the union max_b m_b."""

    def __init__(self, mech: Mechanism, robot: Any, distances: AnalyticDistances, branches: Sequence[str],
                 limits: str, watched: Sequence[int] = (), prescan: Prescan | None = None) -> None:
        self.mech, self.robot, self.distances = mech, robot, distances
        self.branches, self.limits = tuple(branches), limits
        self.watched = np.asarray(watched, dtype=np.int64)
        self.kinematic = mech.margin(self.branches, limits)
        self.prescan = prescan
        """With a pre-scan (of these branches), distances are evaluated only in its close cells:
        elsewhere no pair comes near contact, and m_b = k_b."""

    def branch_distances(self, points: np.ndarray, b: int, inside: np.ndarray, signs: bool = True) -> np.ndarray:
        """(M, P) pair distances at the points `inside` (a mask) in branch b (`signs`: only their
        signs need be right, `AnalyticDistances.distances`)."""
        q = configurations(self.mech, self.robot, points[inside], self.branches[b])
        return self.distances.distances(q, signs=signs)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        kin = self.kinematic(pts)
        B, W = len(self.branches), len(self.watched)
        each = kin[:, :B].copy()
        watch = np.repeat(kin[:, :B, None], W, axis=2)
        cell = self.prescan.cell_index(pts) if self.prescan is not None else None
        for b in range(B):
            inside = kin[:, b] > 0
            if self.prescan is not None:
                inside &= self.prescan.close[b][cell]
            if not inside.any():
                continue
            d = self.branch_distances(pts, b, inside)
            if d.shape[1]:
                each[inside, b] = np.minimum(kin[inside, b], d.min(axis=1))
                watch[inside, b] = np.minimum(kin[inside, b, None], d[:, self.watched])
        return np.column_stack([each, kin[:, :B].max(axis=1), watch.max(axis=1), each.max(axis=1)])


def margin_builder(mech: Mechanism, robot: Any, model: CollisionModel, limits: str = "all"
                   ) -> Callable[[Sequence[str]], CollisionMargin]:
    """Branches -> their collision-aware margin (`CollisionMargin`: each branch's m_b first; a serial
    arm's `SerialCollisionMargin`, the union's last), for analyses that take a margin in place of
    the mechanism's (`usable.usable(margin_of=...)`, `--points`)."""
    dist = AnalyticDistances(model)
    if "reach_search" in mech.capabilities:  # a serial arm: one margin, the union's (`analyses.serial_collisions`)
        from kinematics.analyses.serial_collisions import SerialCollisionMargin, collision_reach

        reach = collision_reach(mech, robot, dist)
        return lambda branches: SerialCollisionMargin(mech, robot, dist, reach)  # type: ignore[return-value]
    return lambda branches: CollisionMargin(mech, robot, dist, branches, limits)


def summary(model: CollisionModel, dist: AnalyticDistances | None = None) -> dict[str, Any]:
    """JSON-ready: pairs checked, closed-form pairs, obstacles, pairs left out (not adjacent)."""
    kinds = (dist if dist is not None else AnalyticDistances(model)).kinds
    return {"pairs_checked": len(model.pairs), "closed_form_pairs": int((kinds != COAL).sum()),
            "obstacles": list(dict.fromkeys(model.obstacles.values())),
            "excluded": [{"first": e.first, "second": e.second, "reason": e.reason} for e in model.excluded
                         if e.reason != "adjacent"]}


def colliding_at(mech: Mechanism, robot: Any, model: CollisionModel, points: np.ndarray, branch: np.ndarray,
                 limits: str = "all") -> np.ndarray:
    """(K,) True where the configuration with the task point at `points[k]` [m] in branch
    `mech.branches[branch[k]]` collides (some pair's signed distance < 0); False where it does
    not, and where the point is outside that branch's kinematic workspace (no configuration)."""
    dist = AnalyticDistances(model)
    pts = np.asarray(points, dtype=float).reshape(len(branch), -1)
    out = np.zeros(len(pts), dtype=bool)
    if not model.pairs:
        return out
    for w in np.unique(branch):
        sel = np.flatnonzero(branch == w)
        name = mech.branches[int(w)]
        sel = sel[mech.margin([name], limits)(pts[sel])[:, 0] > 0]
        if len(sel):
            out[sel] = dist.distances(configurations(mech, robot, pts[sel], name), signs=True).min(axis=1) < 0
    return out


def collision_map(mech: Mechanism, robot: Any, model: CollisionModel, points: np.ndarray, limits: str = "all"
                  ) -> tuple[np.ndarray, np.ndarray]:
    """At each task point (N, d) [m]: the union's collision-aware margin max_b m_b (module
    docstring) and the pair that binds in the best branch among those where the point is inside
    the kinematic workspace (index into `model.pairs`; -1 where the kinematic margin binds or no
    branch reaches the point). A point inside the kinematic workspace collides in every branch iff
    the margin is <= 0 and the pair is >= 0."""
    dist = AnalyticDistances(model)
    margin = CollisionMargin(mech, robot, dist, mech.branches, limits)
    pts = np.asarray(points, dtype=float)
    kin = margin.kinematic(pts)[:, :len(mech.branches)]
    each, pair = kin.copy(), np.full(kin.shape, -1)
    for b in range(len(mech.branches)):
        inside = kin[:, b] > 0
        if inside.any() and model.pairs:
            d = margin.branch_distances(pts, b, inside)
            k = np.argmin(d, axis=1)
            dmin = d[np.arange(len(d)), k]
            each[inside, b] = np.minimum(kin[inside, b], dmin)
            pair[inside, b] = np.where(dmin < kin[inside, b], k, -1)
    # the pair of the best branch among those with a configuration there (kinematic margin > 0)
    best = np.argmax(np.where(kin > 0, each, -np.inf), axis=1)
    return each.max(axis=1), pair[np.arange(len(pts)), best]


@dataclass(frozen=True)
class PairRemoval:
    """Volume [m^3] (area [m^2]) a binding pair removes from the kinematic union when it alone is
    checked, with its error estimate (the two measures' estimates added)."""

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
    `search` and `turn` entries."""
    from kinematics.analyses.serial_collisions import serial_margin

    plain, env = serial_margin(mech, robot, cm, dist, turn)
    on, shape = plain.profile_margin, plain.profile  # a solid of revolution: its profile is scanned
    scan = (Prescan(plain, lo, hi, SERIAL_PRESCAN_CELLS) if on is None or shape is None
            else Prescan(on, shape.lo, shape.hi, PRESCAN_CELLS))
    found, watched = _binding(scan, watch)
    r = plain.reach
    route = "envelope" if env is not None else "profile" if shape is not None else r.setup.mode
    extra = {"search": {"mode": r.setup.mode, "samples": r.samples, "restarts": r.restarts},
             "turn": {"route": route}}
    return plain.with_prescan(watched, scan), scan, found, watched, env, extra


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
    mech.require("margin", "a workspace measurement")
    if mech.task_dim not in (2, 3):
        raise MissingCapabilityError(mech.name, "margin", "a workspace area or volume", mech.capabilities)
    chosen = mech.check_branches(branches)
    mech.check_limits(limits)
    cm = collision_model if collision_model is not None else collision_model_of(robot, obstacles, self_collisions)
    dist = AnalyticDistances(cm)
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
            extra["turn"] = {**bounds, "enveloped": [
                {"link": link, "geometry": name, "bands": [{"from_m": b.lo, "to_m": b.hi, "radius_m": b.radius}
                                                           for b in bands]} for link, name, bands in env.enveloped]}
            if not res.target_converged[-1] and turn == "auto":  # the bracket is too wide: in 3-D
                return in_3d({**extra["turn"], "why": "the envelope's bracket did not meet the tolerance"})
        else:
            res = _take(res, [*range(B), B + 1 + W])
    if env is not None:
        cm = env.model
    ws = Workspace(mech.name, mech.task_dim == 2, (*chosen, UNION), limits, res,
                   time.perf_counter() - t0, mech.parameters(), "elbows" if mech.branch_kind == "elbow" else "modes")
    pairs = tuple(PairRemoval(cm.pair_links[k], cm.pair_names[k], removed, error, count)
                  for (k, count), (removed, error) in zip(found[:watch], removals, strict=True))
    return CollisionWorkspace(ws, kin, kin_err, pairs, tuple(cm.pair_links[k] for k, _ in found[watch:]),
                              {**summary(cm, dist), "pairs_that_can_bind": int(scan.active.sum()), **extra})
