"""Whether a serial arm's possibly singular configurations collide (`singularities ROBOT
--collisions` / `--obstacles FILE`).

The singular scan (`kinematics.analyses.serial_workspace`) lists joint boxes that may hold a
rank-deficient position Jacobian, each by its centre c (joint values) and half-widths w. Each
listed box is judged at its centre: the configuration c collides when some checked pair has a
negative signed distance there (`AnalyticDistances.distances`: closed forms, coal for meshes;
the full distances, not the signs-only ones, whose positive values are clamped or bounded
far below the gap and would certify little below), and the pair with the smallest distance
binds. The other configurations of the box may
differ: the verdict is the centre's, with the box's half-widths beside it. A bound settles the
whole box where the centre is clear enough (`box_free`): moving joint i by dq_i moves every point
of a body it carries by at most R_i |dq_i| (R_i: the path's joint offsets from joint i's origin,
prismatic travels included, plus the body's bounding sphere; 1 for a prismatic joint i), and a
pair's gap changes only through the joints carrying exactly one of its bodies, so

    g_p(q) >= g_p(c) - sum_i w_i R_ip   over the box |q_i - c_i| <= w_i,

and the box is free (at the listed base angle) where every pair's distance at c exceeds its
sum. These offsets hold in every configuration, so the bound is loose (on the ur5's boxes it
settles few); a box it does not settle may still be free. Joints that never move the frame
(`fixed_joints`) are not in the boxes: they stay at their listed values.

The base's turn. A revolved arm's boxes are found with its full-turn base joint at its listed
value (the workspace a solid of revolution): each box stands for its configurations at every base
angle psi (a turn of the base keeps the position Jacobian's rank). Per checked pair:

* both bodies carried by the base joint, or neither: the pair turns rigidly (or not at all), its
  distance is the same at every psi; with only such pairs (`base_angle` "invariant") each verdict
  holds at every base angle;
* one body carried, the other fixed (the base link, an obstacle): its distance changes with psi.
  Then (`base_angle` "varies") the base angles at which the centre is collision-free are
  certified: turning by dpsi moves every point of the carried body by at most r dpsi, r its
  largest distance from the base axis (its geometry's bounding sphere, the same at every psi), so
  the true gap g (1-Lipschitz in the bodies' displacement) obeys g(psi) >= g(psi0) - r |psi -
  psi0|. Each positive reported distance is at most the true gap (exact, or the convex hulls'
  distance, a lower bound), so an interval of half-width h about psi0 is free when every
  varying pair's distance at psi0 exceeds r h (and every other pair's is positive). The turn is
  bisected from START intervals until each is certified or at most `step` wide; such an interval
  whose centre is free is a free sample (one free angle, its neighbourhood not certified), one
  whose centre collides a colliding sample. Verdict per box: "every" (the certified intervals
  cover the turn), "some" (a certified interval or a free sample), "none" (a pair that does not
  change with psi collides: colliding at every angle), "none found" (every sample collides; a
  free set narrower than `step` between samples is not excluded: negative distances are
  penetration depths or coal's contact flags, which carry no Lipschitz bound).

A planar or spatial scan's boxes hold every joint, the base's included (`base_angle` "in the
configuration"): the centre's verdict is the configuration's own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from kinematics.generic.batched import BatchedKinematics, configurations
from kinematics.generic.capsules import AnalyticDistances
from kinematics.generic.collision import CollisionModel

STEP = math.radians(1.0)
"""[rad] The base-angle bisection stops at intervals this wide (default; the CLI's --base-step-deg)."""

START = 16
"""Intervals the base's turn is first cut into."""

BaseAngle = Literal["invariant", "varies", "in the configuration"]
Verdict = Literal["every", "some", "none", "none found"]


@dataclass(frozen=True, eq=False)
class SingularCollisions:
    """Collision verdicts at K listed singular configurations (module docstring).

    Attributes:
        depth: (K,) smallest signed distance [m] at each configuration as listed (+inf: no pair).
        pair: (K,) the pair that has it (index into the model's pairs; -1: no pair).
        base_angle: how the base's angle enters (module docstring).
        base_joint: the base joint's degree-of-freedom index ("varies" only, else -1).
        free_intervals: per configuration, (F, 2) base-joint values [rad] certified free
            ("varies" only; else empty).
        free_samples: (K,) sampled base angles found free but not certified on an interval.
        samples: (K,) base angles evaluated; colliding_samples: (K,) those at which it collides.
        verdict: (K,) "every", "some", "none" or "none found" ("varies" only; else the
            listed configuration's: "every" free or "none").
        step: [rad] the bisection's finest interval width.
        box_free: (K,) the whole box is certified free at the listed base angle (at every base
            angle when "invariant") by the joints' Lipschitz bound (module docstring).
    """

    depth: np.ndarray
    pair: np.ndarray
    base_angle: BaseAngle
    base_joint: int
    free_intervals: tuple[np.ndarray, ...]
    free_samples: np.ndarray
    samples: np.ndarray
    colliding_samples: np.ndarray
    verdict: np.ndarray
    step: float
    box_free: np.ndarray

    @property
    def colliding(self) -> np.ndarray:
        """(K,) True where the configuration as listed collides."""
        return self.depth < 0

    def free_measure(self) -> np.ndarray:
        """(K,) total width [rad] of the certified free base-angle intervals."""
        return _widths(self.free_intervals)


def singular_collisions(robot: Any, ws: Any, model: CollisionModel, values: np.ndarray,
                        half: np.ndarray | None = None, step: float = STEP) -> SingularCollisions:
    """The collision verdicts at the singular boxes' centres `values` ((K, nv) joint values) of
    the scan `ws` (a `SerialWorkspace` of `robot`), its pairs those of `model`.

    Args:
        half: (K, nv) the boxes' half-widths [rad or m] (default: none settled, `box_free` False).
        step: [rad] the base-angle intervals' finest width where the verdict depends on that angle.

    Raises:
        InvalidInputError: step not positive.
    """
    from kinematics.errors import InvalidInputError
    from kinematics.mechanisms.serial.joint_box import dof_of

    if not (step > 0 and math.isfinite(step)):
        raise InvalidInputError("step", f"must be a positive angle [rad], got {step}")
    values = np.asarray(values, dtype=float).reshape(-1, robot.nv)
    dist = AnalyticDistances(model)
    K, P = len(values), len(model.pairs)
    D = dist.distances(configurations(robot, values)) if K else np.zeros((0, P))
    depth, pair = _smallest(D)
    if half is None:
        box = np.zeros(K, dtype=bool)
    else:
        w = np.asarray(half, dtype=float).reshape(K, robot.nv)
        rates = _box_rates(robot, model)
        bound = np.where(w[:, :, None] > 0, w[:, :, None] * rates[None], 0.0).sum(axis=1)
        box = (bound < D).all(axis=1)
    none: tuple[np.ndarray, ...] = tuple(np.zeros((0, 2)) for _ in range(K))
    listed = np.where(depth < 0, "none", "every")
    zeros = np.zeros(K, dtype=np.int64)
    if ws.mode != "revolved":
        return SingularCollisions(depth, pair, "in the configuration", -1, none, zeros, zeros, zeros, listed, step, box)
    v0 = int(BatchedKinematics.from_robot(robot, ws.frame).idx_v[0])
    joint = next(j for j in range(1, robot.model.njoints) if robot.model.joints[j].idx_v == v0)
    carried = set(robot.model.subtrees[joint])
    objs = model.geometry.geometryObjects
    moves = np.array([int(objs[a].parentJoint) in carried for a, _ in model.pairs], dtype=bool)
    other = np.array([int(objs[b].parentJoint) in carried for _, b in model.pairs], dtype=bool)
    varies = moves ^ other
    if not varies.any() or not K:
        return SingularCollisions(depth, pair, "invariant", -1, none, zeros, zeros, zeros, listed, step, box)
    body = np.where(moves, np.array([a for a, _ in model.pairs]), np.array([b for _, b in model.pairs]))
    r = _axis_radii(robot, model, configurations(robot, values), ws.axis_origin, ws.axis_direction)[:, body[varies]]
    base = dof_of(robot, v0)
    free, samples, count, hits = _bisect(robot, dist, values, base, varies, r, D, step)
    meas = _widths(free)
    stuck = (D[:, ~varies] < 0).any(axis=1) if (~varies).any() else np.zeros(K, dtype=bool)
    verdict = np.where(meas >= 2 * math.pi * (1 - 1e-12), "every",
                       np.where((meas > 0) | (samples > 0), "some", np.where(stuck, "none", "none found")))
    return SingularCollisions(depth, pair, "varies", base, tuple(free), samples, count, hits, verdict, step, box)


def _widths(intervals: Any) -> np.ndarray:
    """(K,) total width of each configuration's (F, 2) intervals."""
    return np.array([float((f[:, 1] - f[:, 0]).sum()) for f in intervals])


def _smallest(D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if D.shape[1] == 0:
        return np.full(len(D), np.inf), np.full(len(D), -1)
    k = np.argmin(D, axis=1)
    return D[np.arange(len(D)), k], k


def _box_rates(robot: Any, model: CollisionModel) -> np.ndarray:
    """(nv, P) R_ip [m/rad, or 1 for a prismatic joint]: the most a pair's gap changes per unit of
    joint i, in any configuration (module docstring); 0 where joint i carries both bodies or
    neither, inf where a travel is unbounded."""
    pm = robot.model
    objs = model.geometry.geometryObjects
    reach = []
    for c, rad, place in _spheres(model):  # each geometry's farthest point from its joint's origin
        reach.append(float(np.linalg.norm(place.act(c))) + rad if math.isfinite(rad) else math.inf)
    kinds = {d.idx_v: d for d in robot.dofs}
    hop = np.zeros(pm.njoints)  # joint k's origin from its parent joint's, at most [m]
    for k in range(1, pm.njoints):
        d = kinds.get(pm.joints[k].idx_v)
        travel = max(abs(d.lower), abs(d.upper)) if d is not None and d.kind == "prismatic" else 0.0
        hop[k] = float(np.linalg.norm(pm.jointPlacements[k].translation)) + travel
    out = np.zeros((robot.nv, len(model.pairs)))
    for i, dof in enumerate(robot.dofs):
        j = next(k for k in range(1, pm.njoints) if pm.joints[k].idx_v == dof.idx_v)
        carried = set(pm.subtrees[j])

        def rate(g: int, j: int = j, carried: set[int] = carried, prismatic: bool = dof.kind == "prismatic") -> float:
            if prismatic:
                return 1.0
            k, total = int(objs[g].parentJoint), reach[g]
            while k != j:
                total, k = total + hop[k], int(pm.parents[k])
            return total

        for n, (a, b) in enumerate(model.pairs):
            ca, cb = int(objs[a].parentJoint) in carried, int(objs[b].parentJoint) in carried
            if ca != cb:
                out[i, n] = rate(a if ca else b)
    return out


def _spheres(model: CollisionModel) -> list[tuple[np.ndarray, float, Any]]:
    """Each geometry's bounding sphere (centre in its own frame, radius [m]; inf for an unbounded
    shape, a half-space) and its placement in its joint's frame."""
    out = []
    for g in model.geometry.geometryObjects:
        g.geometry.computeLocalAABB()
        c, rad = np.asarray(g.geometry.aabb_center, dtype=float), float(g.geometry.aabb_radius)
        ok = math.isfinite(rad) and np.isfinite(c).all()
        out.append((c if ok else np.zeros(3), rad if ok else math.inf, g.placement))
    return out


def _axis_radii(robot: Any, model: CollisionModel, q: np.ndarray, origin: np.ndarray,
                direction: np.ndarray) -> np.ndarray:
    """(K, G) largest distance [m] of each geometry's points from the axis (origin, direction) at
    configurations q: its bounding sphere's centre's distance plus the sphere's radius."""
    import pinocchio as pin

    local = [(c, rad) for c, rad, _ in _spheres(model)]
    data, gdata = robot.model.createData(), pin.GeometryData(model.geometry)
    out = np.empty((len(q), len(local)))
    a = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    for n, qn in enumerate(q):
        pin.forwardKinematics(robot.model, data, qn)
        pin.updateGeometryPlacements(robot.model, data, model.geometry, gdata)
        for k, (c, rad) in enumerate(local):
            rel = gdata.oMg[k].act(c) - origin
            out[n, k] = np.linalg.norm(rel - (rel @ a) * a) + rad if math.isfinite(rad) else math.inf
    return out


def _bisect(robot: Any, dist: AnalyticDistances, values: np.ndarray, base: int, varies: np.ndarray,
            r: np.ndarray, D0: np.ndarray, step: float
            ) -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray]:
    """Per configuration, the certified free base-joint intervals (merged), the free samples, the
    angles evaluated and those colliding, bisecting the turn about each listed base value (module docstring)."""
    K = len(values)
    half0 = math.pi / START
    box = np.repeat(np.arange(K), START)
    centre = values[box, base] + (np.tile(np.arange(START), K) * 2 + 1 - START) * half0
    half = np.full(len(box), half0)
    steady = np.all(D0[:, ~varies] > 0, axis=1)  # the pairs the turn leaves alone are apart
    found: list[list[tuple[float, float]]] = [[] for _ in range(K)]
    samples = np.zeros(K, dtype=np.int64)
    count = np.zeros(K, dtype=np.int64)
    hits = np.zeros(K, dtype=np.int64)
    while len(box):
        q = values[box].copy()
        q[:, base] = centre
        D = dist.distances(configurations(robot, q))[:, varies]
        np.add.at(count, box, 1)
        np.add.at(hits, box[~steady[box] | (D < 0).any(axis=1)], 1)
        ok = steady[box] & (r[box] * half[:, None] < D).all(axis=1)
        for b, c, h in zip(box[ok], centre[ok], half[ok], strict=True):
            found[b].append((c - h, c + h))
        leaf = ~ok & (2 * half <= step * (1 + 1e-9))
        np.add.at(samples, box[leaf & steady[box] & (D > 0).all(axis=1)], 1)
        split = ~ok & ~leaf
        box = np.repeat(box[split], 2)
        h = half[split] / 2
        centre = (centre[split][:, None] + np.array([-1.0, 1.0]) * h[:, None]).ravel()
        half = np.repeat(h, 2)
    return [_merge(f) for f in found], samples, count, hits


def _merge(intervals: list[tuple[float, float]]) -> np.ndarray:
    """Touching intervals joined, sorted: (F, 2)."""
    out: list[list[float]] = []
    for lo, hi in sorted(intervals):
        if out and lo <= out[-1][1] + 1e-12:
            out[-1][1] = max(out[-1][1], hi)
        else:
            out.append([lo, hi])
    return np.array(out, dtype=float).reshape(-1, 2)


__all__ = ["STEP", "SingularCollisions", "singular_collisions"]
