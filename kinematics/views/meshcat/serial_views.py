"""Ready-made views of serial arms: the planar arm (`scara_view`) and any serial robot
(`serial_view`), at a readable default pose (`default_pose`), with their velocity ellipses and
workspaces."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from kinematics.views.meshcat.scene import Scene

NEAR_SINGULAR = 1e-2
"""A pose is flagged "at or near a singularity" when r_min < NEAR_SINGULAR * r_max: the ellipse
is then a sliver nobody can read (at 1e-2, under 3 px on a 0.3 m ellipse in a 600 px view)."""


def default_pose(robot: Any) -> np.ndarray:
    """Joint values [rad or m] to draw a serial robot at when none are given: the middle of the
    joint ranges (a folded, readable pose for most arms), or, if that pose is at or near a
    singularity, the middle moved by alternating +/- min(0.3 half-range, 1 rad) per joint."""
    from kinematics.generic.manipulability import ellipsoid
    from kinematics.generic.serial import task_jacobian

    lo, hi = robot.lower, robot.upper
    bounded = np.isfinite(lo) & np.isfinite(hi)  # a continuous joint's -inf + inf would be NaN
    lo, hi = np.where(bounded, lo, 0.0), np.where(bounded, hi, 0.0)
    mid = (lo + hi) / 2
    if robot.nv == 0:  # nothing moves: the one pose (its Jacobian is 6 x 0, no conditioning to test)
        return mid
    step = np.minimum(0.3 * np.where(bounded, (hi - lo) / 2, np.inf), 1.0)
    offset = step * (-1.0) ** np.arange(robot.nv)
    for q in (mid, mid + offset):
        e = ellipsoid(task_jacobian(robot, robot.configuration(q)))
        if e.radii[0] >= NEAR_SINGULAR * e.radii[-1]:
            return q
    return mid + offset


def _check_pose(scene: Scene, radii: np.ndarray, what: str) -> None:
    if radii[0] < NEAR_SINGULAR * radii[-1]:
        scene.warnings.append(f"{what} is at or near a singularity (smallest/largest radius "
                              f"{radii[0] / radii[-1]:.1g}): the ellipse collapses")


def scara_view(robot: Any, q: np.ndarray | None = None, *, ellipse: bool = False, workspace: bool = False,
               singularities: bool = False, guide: int | None = None, scene: Scene | None = None,
               collisions: Any = None, step: float = 0.02) -> Scene:
    """The planar arm at q [rad] (default: `default_pose`), with its velocity ellipse at the tool,
    its reachable workspace coloured by the smallest radius, the theta2 = 0 singular arc, or an
    animated guidance run; the camera framed on all of it. With `collisions` (a `CollisionModel`)
    the workspace is drawn on a task-space grid of `step` [m] instead: the points where both elbows
    collide apart, by binding pair, the collision-free ones in one colour, and the obstacles."""
    from kinematics.generic.manipulability import ellipsoid
    from kinematics.generic.serial import forward_kinematics, task_jacobian
    from kinematics.mechanisms.scara.closed_form import ScaraParams, fk, manipulability
    from kinematics.views.plots import RADIUS_CMAP, SCARA_SINGULAR_COLOUR

    scene = scene or Scene()
    sp = ScaraParams.from_robot(robot)
    qc = robot.configuration(default_pose(robot) if q is None else q)
    scene.add_robot(robot, qc)
    tool = forward_kinematics(robot, qc).position
    e = ellipsoid(task_jacobian(robot, qc))
    if ellipse:
        scene.add_ellipsoid(tool, e.radii, e.directions, "overlays/ellipse",
                            label="velocity ellipse at the tool [m/s per rad/s]")
        _check_pose(scene, e.radii, "this pose")
    if workspace or singularities:
        t1 = np.linspace(sp.lower[0], sp.upper[0], 90)
        t2 = np.linspace(sp.lower[1], sp.upper[1], 90)
        Q = np.stack(np.meshgrid(t1, t2, indexing="ij"), axis=-1).reshape(-1, 2)
        xy = fk(sp, Q)
        if workspace and collisions is not None:
            _collision_workspace(scene, robot, collisions, step, tool[2])
        elif workspace:
            r = manipulability(sp, Q).radii[:, 0]
            scene.add_points(np.hstack([xy, np.full((len(xy), 1), tool[2])]), r, "overlays/workspace",
                             cmap=RADIUS_CMAP, label="reachable points, coloured by the smallest radius [m per rad/s]")
        if singularities:
            from matplotlib.colors import to_rgb

            from kinematics.mechanisms.scara.joint_space import singular_set

            pts = singular_set(sp)["singular_points"]
            scene.add_points(np.hstack([pts, np.full((len(pts), 1), tool[2] + 0.002)]), name="overlays/singular",
                             colour=to_rgb(SCARA_SINGULAR_COLOUR), size=0.012,
                             label=f"singular: theta2 = 0 ({len(pts)} points)")
    if guide is not None:
        from kinematics.guidance.simulation import run_experiment

        run = run_experiment(guide, sp)
        step = max(1, round(1 / (30 * run.params.dt)))
        scene.animate(robot.name, run.q[::step], 30.0, np.hstack([run.x[::step], np.full((len(run.x[::step]), 1),
                                                                                          tool[2])]))
    scene.fit_camera()
    return scene


def _collision_workspace(scene: Scene, robot: Any, collisions: Any, step: float, z: float) -> None:
    """The planar arm's workspace on a grid of `step` [m] in its plane (at height z [m]): the
    colliding points by binding pair (`collision_views.colliding_overlay`), the free ones, the
    obstacles; the grid's counts in `scene.collision_counts` (`colliding_overlay`)."""
    from kinematics.mechanisms import mechanism_of
    from kinematics.sizes import MAX_VIEW_POINTS, cell_centres, check_points, grid_points
    from kinematics.views.meshcat.collision_views import add_obstacles, colliding_overlay

    mech = mechanism_of(robot)
    lo, hi = mech.bounding_box("all")
    check_points("step", grid_points(lo, hi, step), limit=MAX_VIEW_POINTS, hint=f"{step:g} m is too fine a step for a view")
    grid = cell_centres(lo, hi, step)
    pts = grid[(mech.margin(None, "all")(grid)[:, :-1] >= 0).any(axis=1)]

    def embed(p: np.ndarray) -> np.ndarray:
        return np.hstack([p, np.full((len(p), 1), z)])

    free = colliding_overlay(scene, mech, robot, collisions, pts, "all", step * 0.35, embed, step, len(grid))
    scene.add_points(embed(pts[free]), name="overlays/workspace", colour=(0.2, 0.55, 0.85), size=step * 0.35,
                     opacity=0.5, label=f"collision-free workspace ({int(free.sum())} points)")
    if collisions.obstacles:
        add_obstacles(scene, collisions)


VIEW_CELLS = 100_000
"""Points a serial workspace view draws at most (an exported scene stays a few MB)."""


def serial_view(robot: Any, q: np.ndarray | None = None, *, ellipsoid: bool = False, workspace: Any = None,
                singularities: bool = False, scene: Scene | None = None, collisions: Any = None,
                step: float | None = None, grid: Any = None) -> Scene:
    """Any serial robot at joint values q (default: `default_pose`), with the velocity ellipsoid
    of its tool position; with a `SerialWorkspace` (`kinematics.analyses.serial_workspace`), its certified
    cells as points coloured by the smallest radius sigma_min [m/rad] (grey where no configuration
    was evaluated in the cell) and, with `singularities`, the images of the possibly singular
    boxes; the camera framed on all. With `collisions` (a `CollisionModel`) the workspace is drawn
    on a task-space grid of `step` [m] instead (`serial_collisions.collision_grid`, its default
    step with None): the reached points where every configuration found collides apart, by
    binding pair, the collision-free ones in one colour, and the obstacles; `grid`: that grid
    already computed (a `CollisionGrid` of `collisions`; `step` then unused)."""
    from kinematics.generic.manipulability import ellipsoid as ellipsoid_of
    from kinematics.generic.serial import forward_kinematics, frame_jacobian

    scene = scene or Scene()
    qc = robot.configuration(default_pose(robot) if q is None else q)
    scene.add_robot(robot, qc)
    if collisions is not None:
        _serial_collision_points(scene, robot, collisions, step, grid)
    elif workspace is not None:
        _serial_workspace_points(scene, workspace)
    if singularities and workspace is not None:
        _serial_singular_points(scene, workspace)
    if ellipsoid:
        e = ellipsoid_of(frame_jacobian(robot, qc)[:3])
        # true size unless it would dwarf the arm: then scaled to half the arm's bounding radius
        pts = scene.extent
        size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) / 4
        scale = min(1.0, size / e.radii[-1])
        label = "velocity ellipsoid of the tool [m/s per rad/s]" if scale == 1 else \
            f"velocity ellipsoid of the tool, scaled x{scale:.2g} (largest radius {e.radii[-1]:.3g} m/s per rad/s)"
        scene.add_ellipsoid(forward_kinematics(robot, qc).position, scale * e.radii, e.directions,
                            "overlays/ellipsoid", label=label)
        _check_pose(scene, e.radii, "this pose")
    scene.fit_camera()
    return scene


def _turns(points: int) -> int:
    """Azimuths a revolved profile of `points` points is swept at in a view (VIEW_CELLS points in all)."""
    return max(4, min(48, VIEW_CELLS // max(points, 1)))


def _serial_workspace_points(scene: Scene, w: Any) -> None:
    """The certified cells (a solid of revolution swept at as many angles as VIEW_CELLS allows)
    coloured by smallest radius, subsampled evenly to VIEW_CELLS."""
    cells = int(w.inside.sum())
    pts = w.world_points("inside", turns=_turns(cells))
    per = len(pts) // max(cells, 1)  # a revolved cell's points are consecutive
    values = np.repeat(w.smallest_radius[w.inside], per)
    keep = np.unique(np.linspace(0, max(len(pts) - 1, 0), min(len(pts), VIEW_CELLS)).astype(int))
    pts, values = pts[keep], values[keep]
    known = np.isfinite(values)
    size = 1.5 * w.grid.cell
    if known.any():
        scene.add_points(pts[known], values[known], "overlays/workspace", size=size,
                         label=f"smallest radius sigma_min [m/rad] over the certified cells of {w.frame}")
    if (~known).any():
        scene.add_points(pts[~known], None, "overlays/workspace_unsampled", size=size, colour=(0.7, 0.7, 0.7),
                         opacity=0.4, label="certified cells where no configuration was evaluated")


def _serial_singular_points(scene: Scene, w: Any) -> None:
    """The possibly singular boxes' images, subsampled evenly."""
    import dataclasses

    if not len(w.singular_radius):
        return
    k = len(w.singular_radius)
    idx = np.unique(np.linspace(0, k - 1, min(k, VIEW_CELLS // (5 if w.mode != "revolved" else 40))).astype(int))
    sing = dataclasses.replace(w, singular_points=w.singular_points[idx]).world_points("singular", turns=8)
    scene.add_points(sing, None, "overlays/singular", size=1.5 * w.grid.cell, colour=(0.85, 0.1, 0.1),
                     label=f"possibly singular boxes' images ({k:,} boxes, sample of {len(idx):,})")


def _serial_collision_points(scene: Scene, robot: Any, collisions: Any, step: float | None, grid: Any) -> None:
    """A serial arm's reached grid points (`serial_collisions.collision_grid`): the colliding ones
    by binding pair (`collision_views.pair_clouds`), the collision-free ones, the obstacles; a
    revolved profile's points swept about the base axis (`_turns`); the grid's counts in
    `scene.collision_counts`."""
    from kinematics.analyses.serial_collisions import collision_grid
    from kinematics.analyses.serial_workspace.result import revolve
    from kinematics.mechanisms import mechanism_of
    from kinematics.views.meshcat.collision_views import add_obstacles, pair_clouds

    g = grid if grid is not None else collision_grid(mechanism_of(robot), robot, collisions, step)
    reach = g.margin.reach
    embed: Callable[[np.ndarray], np.ndarray] = reach.world
    what, grid = "points", f"a {'planar' if g.mode == 'planar' else '3-D'} grid"
    if g.axis is not None:  # a profile point stands for its circle about the base axis
        origin, direction = g.axis
        turns = _turns(len(g.points))
        embed = lambda p: revolve(reach.profile_of(p), origin, direction, turns)  # noqa: E731
        what, grid = "profile points", f"a (rho, z) profile grid turned at {turns} azimuths"
    size = g.step * (0.35 if g.axis is None else 0.5)
    pair_clouds(scene, collisions, g.points, ~g.free, g.pair, size, embed, what)
    scene.collision_counts = g.counts()
    scene.add_points(embed(g.points[g.free]), name="overlays/workspace", colour=(0.2, 0.55, 0.85), size=size,
                     opacity=0.5, label=f"collision-free workspace ({int(g.free.sum())} {what}; {grid}, step "
                                        f"{g.step:.4g} m, {g.grid_points:,} points searched)")
    if collisions.obstacles:
        add_obstacles(scene, collisions)
