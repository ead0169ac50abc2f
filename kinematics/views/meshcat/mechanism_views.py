"""Ready-made views of mechanisms through their common interface: any closed-loop model
(`closed_loop_view`, drawn at `closed_loop_pose`), the closed-form parallel robots
(`parallel_view`), a branch's conditioning (`conditioning_view`), and the workspace and
singular-point overlays they share."""

from __future__ import annotations

from typing import Any

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.views.meshcat.scene import Scene


def closed_loop_view(robot: Any, actuators: np.ndarray | None = None, *, workspace: bool = False,
                     singularities: bool = False, limits: str = "all", step: float = 0.05,
                     scene: Scene | None = None, collisions: Any = None) -> Scene:
    """Any URDF + loop sidecar through the generic Pinocchio closed-loop solver: at the sidecar's
    reference configuration, or assembled from actuator values [rad or m]; optionally its workspace
    (grid step `step` [m], through the mechanism's margin: `kinematics.mechanisms.closed_loop`'s
    batched solver, every branch) coloured by conditioning, and its singular points where the
    mechanism gives singular fields; camera framed on all of it. A planar task space is drawn in
    the plane of the end effector's reference position. `collisions` (a `CollisionModel`): the
    workspace points where every branch collides drawn apart, by binding pair, and its obstacles."""
    from kinematics.generic.closedloop import ClosedLoop
    from kinematics.mechanisms import mechanism_of

    scene = scene or Scene()
    loop = ClosedLoop(robot)
    q, note = closed_loop_pose(robot, loop, actuators)
    scene.add_robot(robot, q)
    scene.warnings += [note] if note else []
    _check_closed(scene, robot, loop, q)
    if workspace or singularities:
        import pinocchio as pin

        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, loop.reference)
        at = np.asarray(data.oMf[robot.frame_id()].translation, dtype=float)
        mech = mechanism_of(robot)
        _mechanism_overlays(scene, mech, at, workspace=workspace, singularities=singularities, limits=limits, step=step,
                            robot=robot, collisions=collisions)
        if mech.task_dim == 2:  # look down on a planar workspace
            scene.fit_camera(direction=(0.4, -0.6, 1.0))
            return scene
    scene.fit_camera(direction=_facing(robot, q) if robot.name in scene.skeletons else (1.0, -1.4, 0.9))
    return scene


def _facing(robot: Any, q: np.ndarray) -> tuple[float, float, float]:
    """A camera direction for a skeleton: a planar mechanism seen from in front of its plane
    (along the normal, turned 22 deg sideways and 17 deg up so the joints' cylinders show as
    cylinders); a spatial one from the usual (1, -1.4, 0.9)."""
    from kinematics.generic.serial import common_axis

    n = common_axis(robot.model, q)
    if n is None:
        return (1.0, -1.4, 0.9)
    z = np.array([0.0, 0.0, 1.0])
    if abs(n[2]) > 0.9:  # a horizontal plane: from above
        return (0.4, -0.6, 1.0)
    side = np.cross(z, n)
    d = n - 0.4 * side / np.linalg.norm(side) + 0.3 * z
    return (float(d[0]), float(d[1]), float(d[2]))


def closed_loop_pose(robot: Any, loop: Any, actuators: np.ndarray | None) -> tuple[np.ndarray, str | None]:
    """The configuration a closed-loop model is drawn at, and what the reader must know about it.

    The single place the view's pose is chosen: assembled from `actuators` [rad or m] (the loops
    closed with them held; `ClosedLoop.solve(..., fallback=True)`), else `ClosedLoop.assembly`,
    the sidecar's reference closed by `kinematics.generic.assembly.assemble` where it is open (the
    neutral pose where the sidecar names none, e.g. a Gepetto `robot.yaml`: most Gepetto models
    are exported open at q = 0). Where no closed pose is found the start is drawn, open.

    Returns:
        (Pinocchio configuration, a warning or None).
    """
    from kinematics.generic.assembly import AssemblyError

    if actuators is not None:
        return np.asarray(loop.solve(np.asarray(actuators, dtype=float), fallback=True).q), None
    try:
        found = loop.assembly
    except AssemblyError as exc:
        values = np.zeros(robot.nv)
        for name, value in loop.spec.reference.items():
            values[robot.joint_names.index(name)] = value
        where = "its sidecar's reference" if loop.spec.reference else "the neutral pose (q = 0)"
        return robot.configuration(values), f"{robot.name}: no closed pose found ({exc}); drawn open at {where}"
    note = f"{robot.name}: drawn at {found.description}" if found.found else None
    return np.asarray(found.q), note


OPEN_LOOP_RTOL = 1e-6
"""A drawn closed-loop pose is flagged as open when its largest closure error exceeds this
fraction of the model's length scale: above what a hand-typed reference (6-8 digits) leaves,
far below the assemblies' 1e-10 (`generic.assembly.TOLERANCE`)."""


def _check_closed(scene: Scene, robot: Any, loop: Any, q: np.ndarray) -> None:
    from kinematics.generic.serial import length_scale

    gap = float(np.abs(loop.residual(q)[0]).max()) if loop.n_constraints else 0.0
    if gap > OPEN_LOOP_RTOL * length_scale(robot, q):
        scene.warnings.append(f"{robot.name}: the loops are not closed at the drawn pose (largest closure error "
                              f"{gap:.3g} m or rad)")


def _embed(mech: Any, points: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Task points (N, d) as world points (N, 3): the axes the task lacks stay at `at` [m]."""
    axes = ["xyz".index(a) for a in mech.task_axes]
    out = np.tile(np.asarray(at, dtype=float), (len(points), 1))
    out[:, axes] = points
    return out


def _singular_colours() -> dict[int, tuple[tuple[float, float, float], str]]:
    """Singularity type -> (RGB, label), the colours of `plots.SINGULAR_STYLE`."""
    from matplotlib.colors import to_rgb

    from kinematics.views.plots import SINGULAR_STYLE

    return {k: (to_rgb(c), label) for k, (c, _, label) in SINGULAR_STYLE.items()}


def _mechanism_overlays(scene: Scene, mech: Any, at: np.ndarray, *, workspace: bool, singularities: bool,
                        limits: str, step: float, robot: Any = None, collisions: Any = None) -> None:
    """The workspace (grid points inside some branch, coloured by min(iota_I, iota_II) of the
    best-conditioned branch) and the singular points by type, of any mechanism with a margin
    (and velocity; singular fields for the loci). With `collisions` (a `CollisionModel`) the
    points where every branch collides are drawn apart, by binding pair, and the obstacles; the
    grid's counts in `scene.collision_counts` (`colliding_overlay`)."""
    from kinematics.sizes import MAX_VIEW_POINTS, cell_centres, check_points, grid_points
    from kinematics.views.plots import CONDITIONING_CMAP, LIMITS_TEXT

    if workspace:
        mech.require("margin", "a workspace view")
        lo, hi = mech.bounding_box(limits)
        check_points("step", grid_points(lo, hi, step), limit=MAX_VIEW_POINTS,
                     hint=f"{step:g} m is too fine a step for a view")
        grid = cell_centres(lo, hi, step)
        pts = grid[(mech.margin(None, limits)(grid)[:, :-1] >= 0).any(axis=1)]
        if collisions is not None:
            from kinematics.views.meshcat.collision_views import colliding_overlay

            pts = pts[colliding_overlay(scene, mech, robot, collisions, pts, limits, step * 0.35,
                                        lambda p: _embed(mech, p, at), step, len(grid))]
        cond = np.full(len(pts), -1.0)
        if "velocity" in mech.capabilities and len(pts):
            for v, ok in mech.branch_velocities(pts, mech.branches, limits):
                cond = np.where(ok, np.fmax(cond, np.minimum(v.iota_I, v.iota_II)), cond)
        # small, half-transparent points: the robot stays visible inside its workspace
        scene.add_points(_embed(mech, pts, at), cond, "overlays/workspace", size=step * 0.35,
                         cmap=CONDITIONING_CMAP, vrange=(0.0, 1.0), opacity=0.5,
                         label=f"workspace ({LIMITS_TEXT.get(limits, limits)}{', collision-free' if collisions else ''}), "
                               "coloured by min(\u03b9_I, \u03b9_II), 0 = singular")
    if collisions is not None and collisions.obstacles:
        from kinematics.views.meshcat.collision_views import add_obstacles

        add_obstacles(scene, collisions)
    if singularities:
        from kinematics.analyses.singularities import singular_loci

        mech.require("singular_fields", "a view of singular loci")
        loc = singular_loci(mech, step=step, limits=limits, progress=False).locus
        for k, (rgb, label) in _singular_colours().items():
            sel = loc.inside & (loc.kind == k)
            if sel.any():
                # type I outlines the whole boundary: small and faint, so II / III and the robot show
                scene.add_points(_embed(mech, loc.points[sel][:, :mech.task_dim], at), name=f"overlays/singular_{k}",
                                 colour=rgb, size=0.006 if k == 1 else 0.009, opacity=0.35 if k == 1 else 1.0,
                                 label=f"{label} singular points {'on' if k == 1 else 'in'} the workspace: "
                                       f"{int(sel.sum())}")


def parallel_view(robot: Any, position: np.ndarray | None = None, mode: str | None = None,
                  actuators: np.ndarray | None = None, *, ellipsoid: bool = False, workspace: bool = False,
                  singularities: bool = False, limits: str = "all", step: float = 0.02,
                  scene: Scene | None = None, collisions: Any = None) -> Scene:
    """A closed-form parallel robot (the 3-[P2(US)], the Delta: any mechanism with ik, velocity
    and joint values) at a platform position (closed forms -> actuators -> Pinocchio closed-loop
    solve) or at actuator values, with its velocity ellipsoid (from J), its workspace as a point
    cloud coloured by the conditioning min(iota_I, iota_II) of the best-conditioned branch, and
    its singular points by type; the camera framed on all of it, a warning when the pose is
    singular. `mode`: the working mode of `position` (default: the reference pose's); without a
    position there is nothing for it to choose (at `actuators` the assembly decides the mode, with
    neither the view is at the reference pose) and giving one is an error, as giving both a
    position and actuators is. `collisions` (a `CollisionModel`): as `closed_loop_view`'s."""
    from kinematics.generic.closedloop import ClosedLoop
    from kinematics.generic.manipulability import ellipsoid as ellipsoid_of
    from kinematics.mechanisms import SINGULARITY_TYPES, mechanism_of

    scene = scene or Scene()
    mech = mechanism_of(robot)
    for need in ("ik", "velocity", "joint_values"):
        mech.require(need, "a view of a parallel robot")
    if position is not None and actuators is not None:
        raise InvalidInputError("position", "give a platform position or actuator values, not both")
    if mode is not None and position is None:
        raise InvalidInputError("mode", "the working mode of a position; without one the view is at the actuator "
                                        "values (they decide the mode) or at the reference pose")
    loop = ClosedLoop(robot)
    branches = mech.branches
    if actuators is None:
        reference, default = mech.reference_pose()
        position, mode = (reference, default) if position is None else (position, default if mode is None else mode)
        p = np.asarray(position, dtype=float)
        m = branches.index(mech.check_branches([mode])[0])
        sol = mech.ik(p[None])
        if not sol.reachable[0, m]:
            raise InvalidInputError("position", f"{p.tolist()} is not reachable in {mech.branch_kind} {mode}")
        values = mech.joint_values(p, mode)
        warm = robot.configuration([values[n] for n in robot.joint_names])
        res = loop.solve(sol.q[0, m], q0=warm)
    else:
        res = loop.solve(np.asarray(actuators, dtype=float))
    scene.add_robot(robot, res.q)
    p = np.asarray(res.pose.translation, dtype=float)
    s = mech.ik(p[None])
    m = (branches.index(str(mode)) if actuators is None
         else int(np.nanargmin(np.abs(s.q[0] - np.asarray(actuators, dtype=float)).sum(axis=-1))))
    vel = mech.velocity(p[None], s.q[0, m][None])
    kind = int(vel.types[0])
    if kind:
        scene.warnings.append(f"this pose is singular ({SINGULARITY_TYPES[kind]}: iota_I = {float(vel.iota_I[0]):.2g}, "
                              f"iota_II = {float(vel.iota_II[0]):.2g})")
    if ellipsoid:
        if kind >= 2:
            raise InvalidInputError("position", "J_x is singular (type II): no velocity ellipsoid here")
        e = ellipsoid_of(vel.J[0])
        scene.add_ellipsoid(p, 0.1 * e.radii / e.radii.max(), e.directions, "overlays/ellipsoid",
                            label="velocity ellipsoid of the platform (largest radius drawn 0.1 m)")
    if workspace or singularities:
        _mechanism_overlays(scene, mech, p, workspace=workspace, singularities=singularities, limits=limits,
                            step=step, robot=robot, collisions=collisions)
    # a low camera: the base disk hangs above the mechanism and hides it from the usual 30 deg
    scene.fit_camera(direction=(1.0, -1.4, 0.2))
    return scene


def conditioning_view(mech: Any, branch: str, *, limits: str = "all", step: float | None = None,
                      scene: Scene | None = None) -> Scene:
    """A mechanism's workspace (one branch, or "union": the best branch at each point) as points
    coloured by 1/kappa of the forward Jacobian (0 singular, 1 isotropic); camera framed on them."""
    from kinematics.analyses.dexterity import conditioning_grid
    from kinematics.sizes import MAX_VIEW_POINTS, check_points
    from kinematics.views.plots import INVERSE_KAPPA_CMAP, LIMITS_TEXT

    scene = scene or Scene()
    axes, g = conditioning_grid(mech, branch, limits=limits, step=step)
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(axes))
    step = float(axes[0][1] - axes[0][0]) if len(axes[0]) > 1 else 0.01
    v = g.ravel()
    keep = np.isfinite(v)
    check_points("step", int(keep.sum()), limit=MAX_VIEW_POINTS, hint="use a larger step")
    scene.add_points(pts[keep], v[keep], "overlays/conditioning", size=step * 0.4, cmap=INVERSE_KAPPA_CMAP,
                     vrange=(0.0, 1.0), opacity=0.6,
                     label=f"1/\u03ba of J, {mech.branch_kind} {branch} ({LIMITS_TEXT.get(limits, limits)})")
    scene.fit_camera()
    return scene

