"""Bounding capsules of the shapes coal measures (mesh hulls, boxes, cylinders): closed-form lower
bounds of their pairs' signed distances.

A capsule that contains a shape is at least as close to any other body as the shape is, so for
two shapes A, B inside capsules C_A, C_B (a sphere, capsule or half-space stays itself)

    d(C_A, C_B) <= d(A, B),

and d(C_A, C_B) > 0 proves the pair apart. `kinematics.generic.capsules.AnalyticDistances` uses
this where only a distance's sign matters (`distances(signs=True)`): a coal pair whose capsules are
apart keeps the capsules' distance (a positive lower bound, the sign exact) and coal is asked only
for the others. The ur5's 20 mesh pairs at random configurations: 84 % are proved apart this way
(coal ~13 us a pair, the capsules' closed form ~0.1 us).

The capsule of a point set (a hull's vertices, a box's corners): its axis the points' principal
direction through their centroid, its radius the largest distance of a point from that axis, its
segment the shortest one along the axis that keeps every point within the radius (a point at
height t and distance rho from the axis needs the segment to reach within sqrt(r^2 - rho^2) of t).
A convex hull is inside the capsule when its vertices are (the capsule is convex). A cylinder of
radius R and half length h is inside the capsule of the same axis, radius R and half length h.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

INFLATE = 1e-12
"""[m] Added to a fitted capsule's radius (and relative 1e-12 of it) after the fit: rounding in
the fit (~1e-16 of the coordinates) cannot leave a vertex outside."""


def capsule_of_points(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The capsule (module docstring) holding `points` (K, 3): its centre (3,), unit axis (3,),
    radius [m] and half length [m] (0: a sphere)."""
    P = np.asarray(points, dtype=float).reshape(-1, 3)
    c = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - c, full_matrices=False)
    a = vt[0] / np.linalg.norm(vt[0])
    t = (P - c) @ a
    rho = np.linalg.norm(P - c - np.outer(t, a), axis=1)
    fit = float(rho.max())
    s = np.sqrt(np.maximum(fit * fit - rho * rho, 0.0))
    lo, hi = float((t + s).min()), float((t - s).max())
    if lo > hi:  # every point within the radius of one point of the axis: a sphere there
        lo = hi = 0.5 * (lo + hi)
    return c + 0.5 * (lo + hi) * a, a, fit * (1.0 + 1e-12) + INFLATE, 0.5 * (hi - lo)


def polytope_points(geometry: Any) -> np.ndarray | None:
    """(K, 3) points whose hull is the coal shape `geometry`, in its own frame: a box's corners, a
    convex polytope's vertices; None for other shapes."""
    import coal

    if isinstance(geometry, coal.Box):
        h = np.asarray(geometry.halfSide, dtype=float)
        return np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float) * h
    if isinstance(geometry, coal.ConvexBase):
        return np.asarray(geometry.points(), dtype=float)
    return None


def bounding_capsule(geometry: Any) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """Centre (3,), unit axis (3,), radius and half length [m], in the shape's own frame, of a
    capsule holding the coal shape `geometry` (None: no bound, e.g. a half-space, which has its
    own closed forms, or a shape kind not handled here)."""
    import coal

    if isinstance(geometry, coal.Capsule | coal.Cylinder):
        return np.zeros(3), np.array([0.0, 0.0, 1.0]), float(geometry.radius), float(geometry.halfLength)
    if isinstance(geometry, coal.Sphere):
        return np.zeros(3), np.array([0.0, 0.0, 1.0]), float(geometry.radius), 0.0
    points = polytope_points(geometry)
    return None if points is None else capsule_of_points(points)


@dataclass(frozen=True)
class BoundModel:
    """The pairs of a `CollisionModel` that coal measures, with every shape replaced by its
    bounding capsule (half-spaces kept): the attributes `AnalyticDistances` reads (`robot`,
    `geometry`, `pairs`), so its closed forms give the lower bounds. `of[n]` is pair n's index
    in the collision model."""

    robot: Any
    geometry: Any
    pairs: tuple[tuple[int, int], ...]
    of: np.ndarray

    def distances(self, q: np.ndarray, only: np.ndarray | None = None) -> np.ndarray:
        """Never needed: every pair here has a closed form (a capsule against a capsule or a
        half-space); NaN marks a slip."""
        return np.full((len(q), len(self.pairs)), np.nan)


def bound_model(model: Any, pairs: np.ndarray) -> BoundModel | None:
    """The `BoundModel` of the collision model's pairs `pairs` (indices) that have bounds (both
    shapes bounded, or one bounded and the other a half-space), None if none has."""
    import coal
    import pinocchio as pin

    objs = list(model.geometry.geometryObjects)
    geometry = pin.GeometryModel()
    index: dict[int, int] = {}

    def placed(k: int) -> int | None:
        if k in index:
            return index[k]
        g = objs[k]
        if isinstance(g.geometry, coal.Halfspace):
            shape, placement = g.geometry, g.placement
        else:
            fit = bounding_capsule(g.geometry)
            if fit is None:
                return None
            centre, axis, radius, half = fit
            placement = g.placement * pin.SE3(frame_along(axis), centre)
            shape = coal.Capsule(radius, 2.0 * half)
        index[k] = geometry.ngeoms
        geometry.addGeometryObject(pin.GeometryObject(g.name, g.parentJoint, g.parentFrame, placement, shape))
        return index[k]

    kept, of = [], []
    for n in np.asarray(pairs, dtype=np.int64):
        a, b = model.pairs[int(n)]
        if isinstance(objs[a].geometry, coal.Halfspace) and isinstance(objs[b].geometry, coal.Halfspace):
            continue
        ia, ib = placed(a), placed(b)
        if ia is not None and ib is not None:
            kept.append((ia, ib))
            of.append(int(n))
    if not kept:
        return None
    return BoundModel(model.robot, geometry, tuple(kept), np.array(of, dtype=np.int64))


def frame_along(axis: np.ndarray) -> np.ndarray:
    """A rotation whose z column is the unit vector `axis`."""
    z = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


__all__ = ["INFLATE", "BoundModel", "bound_model", "bounding_capsule", "capsule_of_points", "frame_along", "polytope_points"]
