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
min's. The union's margin is max_b m_b. Its volume (area) is measured by
`kinematics.analyses.collision_volume`.

Obstacles (`kinematics.generic.obstacles`) add pairs (robot body, obstacle) to the same margin;
with `self_collisions=False` they are the only pairs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinematics.analyses.collision_prescan import Prescan
from kinematics.errors import InvalidInputError
from kinematics.generic.capsules import COAL, AnalyticDistances
from kinematics.generic.collision import CollisionModel
from kinematics.generic.obstacles import Obstacles
from kinematics.mechanisms.base import Mechanism


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
    margin needs configurations at task points (`ik`, or a serial arm's reach search; a closed
    loop's joint values besides, `configurations`)."""
    serial = "reach_search" in mech.capabilities
    if ("ik" not in mech.capabilities and not serial) or (mech.closed_loop and "joint_values" not in mech.capabilities):
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
    are all its joints) and from the batched solver for a generic closed loop (NaN rows where it
    finds none: a second solve near a reach boundary can miss what the margin's found), else
    `mech.joint_values` point by point."""
    if mech.family in ("p2us", "delta"):
        from kinematics.mechanisms.delta import urdf as delta_urdf
        from kinematics.mechanisms.p2us import urdf as p2us_urdf

        module: Any = p2us_urdf if mech.family == "p2us" else delta_urdf
        return module.configurations_at(mech.params, robot.model, points, branch)
    import pinocchio as pin

    from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop

    model = robot.model
    out = np.tile(pin.neutral(model), (len(points), 1))
    q = None
    if not mech.closed_loop and "ik" in mech.capabilities:
        q = mech.ik(points).q[:, mech.branches.index(branch)]
    elif isinstance(mech, GenericClosedLoop):  # the batched solver's joint values, loops closed
        q = mech.joint_value_rows(points, branch)
    if q is not None:
        found = np.isfinite(q).all(axis=1) if isinstance(mech, GenericClosedLoop) else slice(None)
        if q.shape[1] != robot.nv or not np.isfinite(q[found]).all():  # as `robot.configuration` would
            for row in q[found]:
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


def found_distances(dist: AnalyticDistances, q: np.ndarray, signs: bool = True) -> np.ndarray:
    """(N, P) every pair's signed distance [m] at configurations q (N, nq) (`dist.distances`), +inf
    in the rows of q holding NaN: where `configurations` found none (a generic loop's solver can
    miss a point near its reach boundary that the margin's own solve reached)."""
    found = np.isfinite(q).all(axis=1)
    if found.all():
        return dist.distances(q, signs=signs)
    out = np.full((len(q), len(dist.kinds)), np.inf)
    out[found] = dist.distances(q[found], signs=signs)
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
        # a point with no configuration gets +inf: the kinematic margin decides there, as where
        # the exact columns' rounding leaves none
        return found_distances(self.distances, configurations(self.mech, self.robot, points[inside],
                                                              self.branches[b]), signs)

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


def binding_pairs(model: CollisionModel, pair: np.ndarray, colliding: np.ndarray) -> list[tuple[tuple[str, str], int]]:
    """The pairs of links that bind at the `colliding` points (mask (N,); `pair` (N,): each point's
    binding pair, an index into `model.pairs`) with their point counts, the most frequent first (a
    pair of links with several shapes, hence several pairs, counted once)."""
    counts: dict[tuple[str, str], int] = {}
    for k, n in zip(*np.unique(pair[colliding], return_counts=True), strict=True):
        links = model.pair_links[int(k)]
        counts[links] = counts.get(links, 0) + int(n)
    return sorted(counts.items(), key=lambda item: -item[1])


@dataclass(frozen=True)
class GridCounts:
    """The counts of a collision view's grid (`show --workspace --collisions/--obstacles`).

    Attributes:
        mode: "planar" (a grid of the task plane), "revolved" (a serial arm's (rho, z) profile: a
            point stands for its circle about the base axis) or "spatial" (3-D).
        step: grid step [m]; grid_points: the grid's points (searched, reached or not).
        reached: points inside the kinematic workspace (a serial arm: reached by its search).
        free: reached points collision-free in some branch (a serial arm: at a configuration found).
        binding_pairs: ((link, link), points) where every branch collides, the most frequent
            first (`binding_pairs`); the colliding points are their sum, reached - free.
    """

    mode: str
    step: float
    grid_points: int
    reached: int
    free: int
    binding_pairs: tuple[tuple[tuple[str, str], int], ...]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: mode, step_m [m], grid_points, reached, free, colliding, binding_pairs
        (links, points)."""
        return {"mode": self.mode, "step_m": self.step, "grid_points": self.grid_points, "reached": self.reached,
                "free": self.free, "colliding": sum(n for _, n in self.binding_pairs),
                "binding_pairs": [{"links": list(k), "points": n} for k, n in self.binding_pairs]}


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
    pts = np.asarray(points, dtype=float).reshape(len(branch), mech.task_dim)
    out = np.zeros(len(pts), dtype=bool)
    if not model.pairs:
        return out
    for w in np.unique(branch):
        sel = np.flatnonzero(branch == w)
        name = mech.branches[int(w)]
        sel = sel[mech.margin([name], limits)(pts[sel])[:, 0] > 0]
        if len(sel):
            # (+inf where a generic loop's solver misses a point: not flagged)
            out[sel] = found_distances(dist, configurations(mech, robot, pts[sel], name), True).min(axis=1) < 0
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
