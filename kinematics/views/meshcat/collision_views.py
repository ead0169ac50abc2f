"""Collisions in a Meshcat scene: the workspace points where every branch collides, grouped by
the pair that binds there, and the obstacles' shapes (`show --workspace --collisions/--obstacles`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from kinematics.views.meshcat.scene import Scene

PAIR_COLOURS = ((0.85, 0.1, 0.1), (0.95, 0.5, 0.0), (0.7, 0.0, 0.55), (0.55, 0.25, 0.05), (0.95, 0.3, 0.45),
                (0.6, 0.6, 0.0))
"""Colours of the binding pairs' points, the most frequent pair first (then cycled)."""

HALFSPACE_SIDE = 1.0
"""Side [m] of the square slab that draws a half-space's face (a half-space has no extent)."""


def colliding_overlay(scene: Scene, mech: Any, robot: Any, model: Any, points: np.ndarray, limits: str,
                      size: float, embed: Callable[[np.ndarray], np.ndarray], step: float, grid_points: int
                      ) -> np.ndarray:
    """Draw the points (inside the kinematic workspace) where every branch collides, one cloud
    per binding pair (`analyses.collisions.collision_map`, `pair_clouds`), and record the counts
    of the grid of `step` [m] and `grid_points` points they were kept from in
    `scene.collision_counts` (a `GridCounts`); returns the mask of the points that are
    collision-free in some branch."""
    from kinematics.analyses.collisions import GridCounts, collision_map

    margin, pair = collision_map(mech, robot, model, points, limits)
    colliding = (margin <= 0) & (pair >= 0)  # a zero kinematic margin is the workspace's own boundary
    pairs = pair_clouds(scene, model, points, colliding, pair, size, embed)
    scene.collision_counts = GridCounts("planar" if mech.task_dim == 2 else "spatial", float(step), int(grid_points),
                                        len(points), int((~colliding).sum()), tuple(pairs))
    return ~colliding


def pair_clouds(scene: Scene, model: Any, points: np.ndarray, colliding: np.ndarray, pair: np.ndarray, size: float,
                embed: Callable[[np.ndarray], np.ndarray], what: str = "points") -> list[tuple[tuple[str, str], int]]:
    """Draw the `colliding` points, one cloud per binding pair of links (`pair`: index into the
    model's pairs; a link with several shapes has several pairs), the most frequent first, each
    labelled with its links and its count of `what`; returns those pairs with their counts
    (`analyses.collisions.binding_pairs`)."""
    from kinematics.analyses.collisions import binding_pairs

    pairs = binding_pairs(model, pair, colliding)
    for n, ((a, b), count) in enumerate(pairs):
        sel = colliding & np.isin(pair, [k for k in range(len(model.pairs)) if model.pair_links[k] == (a, b)])
        scene.add_points(embed(points[sel]), name=f"overlays/colliding/{a}--{b}", colour=PAIR_COLOURS[n % len(PAIR_COLOURS)],
                         size=size, opacity=0.8, label=f"colliding: {a} - {b} binds ({count} {what})")
    return pairs


def add_obstacles(scene: Scene, model: Any) -> int:
    """Draw each obstacle of a `CollisionModel` as a translucent mesh (a half-space as a slab of
    its face, `HALFSPACE_SIDE` wide, about the point of the face nearest the origin); returns how
    many were drawn."""
    drawn = 0
    for k, body in model.obstacles.items():
        g = model.geometry.geometryObjects[k]
        mesh = _trimesh_of(g.geometry)
        if mesh is None:
            scene.warnings.append(f"obstacle {body}: shape {type(g.geometry).__name__} not drawn")
            continue
        mesh.apply_transform(g.placement.homogeneous)
        scene.add_mesh(mesh.vertices, mesh.faces, name=f"obstacles/{g.name}", colour=(0.45, 0.45, 0.5), opacity=0.35,
                       label=f"obstacle {body}")
        drawn += 1
    return drawn


def _trimesh_of(shape: Any) -> Any:
    """A `trimesh.Trimesh` of a coal shape in its own frame, or None for a shape not drawn."""
    import coal
    import trimesh

    if isinstance(shape, coal.Box):
        return trimesh.creation.box(extents=2 * np.asarray(shape.halfSide))
    if isinstance(shape, coal.Sphere):
        return trimesh.creation.icosphere(subdivisions=2, radius=shape.radius)
    if isinstance(shape, coal.Capsule):
        return trimesh.creation.capsule(height=2 * shape.halfLength, radius=shape.radius)
    if isinstance(shape, coal.Cylinder):
        return trimesh.creation.cylinder(radius=shape.radius, height=2 * shape.halfLength)
    if isinstance(shape, coal.Halfspace):
        n = np.asarray(shape.n, dtype=float)
        slab = trimesh.creation.box(extents=(HALFSPACE_SIDE, HALFSPACE_SIDE, 0.002))
        z = np.array([0.0, 0.0, 1.0])
        axis = np.cross(z, n)
        angle = float(np.arctan2(np.linalg.norm(axis), z @ n))
        if np.linalg.norm(axis) > 1e-12:
            slab.apply_transform(trimesh.transformations.rotation_matrix(angle, axis))
        elif n[2] < 0:
            slab.apply_transform(trimesh.transformations.rotation_matrix(np.pi, [1.0, 0.0, 0.0]))
        slab.apply_translation(shape.d * n - 0.001 * n)  # the slab's upper face on the plane
        return slab
    if isinstance(shape, coal.ConvexBase):
        return trimesh.convex.convex_hull(np.array(shape.points()))
    return None
