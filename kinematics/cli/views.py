"""`kinematics show`: a Meshcat view of a robot with overlays, served live or exported as HTML."""

from __future__ import annotations

import argparse
import time
from typing import Any

from kinematics.cli.args import (
    Command,
    collision_args,
    collision_checks,
    load,
    mode_of,
    non_negative,
    number,
    positive,
    refuse_pose_args,
    refuse_serial_args,
    robot_arg,
    serial_args,
)
from kinematics.cli.report import Out, compile_notice, emit, with_plane
from kinematics.errors import InvalidInputError


def register(command: Command) -> None:
    p = command("show", cmd_show, "Meshcat view with overlays: prints the viewer URL and serves until "
                                   "interrupted, or writes a static HTML scene with --export")
    robot_arg(p)
    p.add_argument("--q", nargs="+", type=number, metavar="Q",
                   help="joint values [rad or m]; closed loops: the actuator values (closed-loop solved)")
    p.add_argument("--degrees", action="store_true", help="revolute joint values are in degrees")
    p.add_argument("--position", nargs=3, type=number, metavar=("X", "Y", "Z"),
                   help="p2us, delta: platform position [m] (default: the sidecar's reference pose; not with --q)")
    p.add_argument("--mode", help="p2us, delta: working mode for --position (default ---)")
    p.add_argument("--ellipsoid", action="store_true", help="the manipulability ellipse/ellipsoid at the tool")
    p.add_argument("--workspace", action="store_true",
                   help="the workspace as points coloured by smallest radius (arms) or min(iota_I, iota_II) "
                        "(closed loops: p2us, delta, any URDF + sidecar)")
    p.add_argument("--singularities", action="store_true", help="the singular points")
    p.add_argument("--guide", type=int, choices=[1, 2, 3], help="planar arm: animate guidance experiment N")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="closed loops: limits for --workspace")
    p.add_argument("--step", type=positive, default=None, metavar="M",
                   help="closed loops: grid step [m] (default 0.02; 0.05 for a generic closed loop, whose solver is "
                        "slower); serial arms with --collisions/--obstacles: default the task box's longest side / 24 "
                        "(/ 48 on a revolved arm's profile or a plane; each reached point costs a search and every "
                        "pair's distance: the ur5's 3,184 points about 1.5 s)")
    serial_args(p)
    p.add_argument("--skeleton", action="store_true",
                   help="also draw the kinematic skeleton: joints along their axes, links joint to joint, loop-closure "
                        "frames, the end effector (drawn anyway for a robot whose mesh files are missing)")
    p.add_argument("--mesh", metavar="FILE", help="also draw a triangle mesh (.stl, .ply, .glb), e.g. a workspace "
                                                  "boundary from `workspace-mesh`")
    collision_args(p, "; with --workspace: the points where every branch collides drawn by binding pair, and "
                      "the obstacles (p2us, delta, the planar arm, closed loops, serial arms: the best configuration their "
                      "search finds, on a --step grid; their counts printed, --json key collisions: mode, step_m, "
                      "grid_points, reached, free, colliding, binding_pairs)")
    p.add_argument("--export", metavar="FILE.html", help="write a self-contained HTML scene and exit")
    p.add_argument("--serve-seconds", type=non_negative, metavar="S", help=argparse.SUPPRESS)


def cmd_show(args: argparse.Namespace) -> int:
    """Meshcat view of a robot with overlays."""
    robot = load(args)
    return run(args, robot, with_plane(robot, emit))


GUIDE_ROBOTS = ("guidance runs are for planar arms of the scara family (planar 2R arms with closed forms, joint "
                "axes along z), which {} is not")
"""--guide's refusal: a planar arm such as the double pendulum (axes along x) is not enough."""


def run(args: argparse.Namespace, robot: Any, out: Out) -> int:
    import signal
    import sys

    import numpy as np

    from kinematics.cli.parallel import POSE_REPORTS, actuated_arg
    from kinematics.mechanisms import mechanism_of
    from kinematics.views import meshcat as viz

    mech = mechanism_of(robot)
    if args.workspace:  # its scan (a generic closed loop: the batched solver)
        compile_notice(args, mech.kernels())
    three_limb = mech.capabilities >= POSE_REPORTS  # the closed-form parallel robots (`parallel_view`)
    # a closed loop's --q: its actuator values, checked and with --degrees applied, for every use below
    actuators = None if args.q is None or robot.loops is None else actuated_arg(args, robot)
    checks = None
    if args.collisions or args.obstacles:
        if not args.workspace:
            raise InvalidInputError("--collisions/--obstacles", "drawn with --workspace")
        checks = collision_checks(args, robot)
    if three_limb:
        if args.position is not None and actuators is not None:
            raise InvalidInputError("--position/--q", "give one of them, not both")
        unreachable = _parallel_checks(args, robot, mech, actuators)
        if unreachable is not None:
            where = (f"platform at {unreachable['position']} m in mode {unreachable['mode']}"
                     if unreachable["position"] is not None else f"actuators at {unreachable['q']} {mech.actuator_unit}")
            out(args, unreachable, lambda: f"{where} is NOT reachable: {unreachable['reason']}")
            return 1
    if not three_limb:
        what = "joint values" if robot.loops is None else "actuator values"
        refuse_pose_args(args, f"poses the p2us and the Delta; give {robot.name}'s {what} with --q")
    elif args.mode is not None and args.position is None:
        raise InvalidInputError("--mode", "the working mode of --position; without it the view is at --q's actuators "
                                          "(they decide the mode) or at the reference pose")
    # a serial arm's cell engine (`serial_scan`) draws its --singularities and collision-free --workspace
    cell_engine = (robot.loops is None and not three_limb and "joint_singularities" not in mech.capabilities
                   and ((args.workspace and checks is None) or args.singularities))
    if not cell_engine:  # before the scene: bad input starts no server
        refuse_serial_args(args, "show runs it only for a serial arm's --singularities, or its --workspace without collisions")
    grid = _serial_collision_grid(args, robot, mech, checks)
    mesh = _load_mesh(args.mesh) if args.mesh else None
    if not args.export:
        # SIGTERM must end the meshcat server too (it outlives its parent otherwise)
        signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    scene = viz.Scene(live=not args.export, skeleton=args.skeleton)
    try:
        if three_limb:
            if args.guide is not None:
                raise InvalidInputError("--guide", GUIDE_ROBOTS.format(robot.name))
            viz.parallel_view(robot, None if args.position is None else np.array(args.position), args.mode,
                          actuators, ellipsoid=args.ellipsoid, workspace=args.workspace,
                          singularities=args.singularities, limits=args.limits,
                          step=0.02 if args.step is None else args.step, scene=scene, collisions=checks)
        elif robot.loops is None:  # an open chain: joint values drive it
            q = robot.values_from_configuration(robot.configuration(args.q, degrees=args.degrees)) \
                if args.q is not None else None
            if "joint_singularities" in mech.capabilities:  # a planar arm with closed forms
                viz.scara_view(robot, q, ellipse=args.ellipsoid, workspace=args.workspace,
                               singularities=args.singularities, guide=args.guide, scene=scene, collisions=checks,
                               step=0.02 if args.step is None else args.step)
            else:
                if args.guide is not None:
                    raise InvalidInputError("--guide", GUIDE_ROBOTS.format(robot.name))
                ws = None
                if cell_engine:
                    from kinematics.cli.singular import serial_scan

                    ws = serial_scan(args, robot)
                viz.serial_view(robot, q, ellipsoid=args.ellipsoid, workspace=ws, singularities=args.singularities,
                                scene=scene, collisions=checks, step=args.step, grid=grid)
        else:
            viz.closed_loop_view(robot, actuators,
                                 workspace=args.workspace, singularities=args.singularities, limits=args.limits,
                                 step=0.05 if args.step is None else args.step, scene=scene, collisions=checks)
        if mesh is not None:
            scene.add_mesh(mesh.vertices, mesh.faces, label=f"mesh {args.mesh}")
            scene.fit_camera()
        print("".join(f"warning: {w}\n" for w in scene.warnings) + "".join(f"  not drawn: {s}\n" for s in scene.skipped),
              end="", file=sys.stderr)
        notes: dict[str, Any] = {"warnings": scene.warnings, "skipped_visuals": scene.skipped}
        report = ""
        if scene.collision_counts is not None and checks is not None:
            from kinematics.analyses.collisions import summary

            notes["collisions"] = {**summary(checks, None if grid is None else grid.margin.distances),
                                   **scene.collision_counts.as_dict()}
            report = _grid_report(notes["collisions"], searched=grid is not None) + "\n"
        if args.export:
            scene.export(args.export)
            payload = {"robot": robot.name, "export": args.export, **notes}
            out(args, payload, lambda: f"{report}wrote {args.export}")
            return 0
        payload = {"robot": robot.name, "url": scene.url, **notes}
        out(args, payload,
            lambda: f"{report}Meshcat viewer for {robot.name}: {scene.url}\n(serving; Ctrl-C to stop)")
        sys.stdout.flush()
        try:
            if args.serve_seconds is not None:
                time.sleep(args.serve_seconds)
            else:
                while True:
                    time.sleep(0.5)
        except KeyboardInterrupt:
            pass
        return 0
    finally:
        scene.close()


def _serial_collision_grid(args: argparse.Namespace, robot: Any, mech: Any, checks: Any) -> Any:
    """A serial arm's collision grid for `--workspace --collisions/--obstacles`
    (`serial_collisions.collision_grid`, for a mechanism with a reach search; None for the other
    robots, whose views split their own grids, and without checks), computed before the scene
    starts so bad input starts no server."""
    if checks is None or "reach_search" not in mech.capabilities:
        return None
    from kinematics.analyses.serial_collisions import collision_grid

    if args.limits != "all":
        raise InvalidInputError("--limits", "a serial arm has its URDF's joint limits only: use all")
    return collision_grid(mech, robot, checks, args.step)


def _grid_report(c: dict[str, Any], searched: bool) -> str:
    """The human lines of a collision view's grid (`GridCounts.as_dict` with the model's
    `summary`): the grid, the points reached (`searched`: by a serial arm's search; else inside
    the kinematic workspace), free and colliding, the binding pairs."""
    from kinematics.cli.report import fmt, key_values

    what = "profile points" if c["mode"] == "revolved" else "points"
    grid = {"revolved": "(rho, z) profile grid (a point stands for its circle about the base axis)",
            "planar": "grid of the plane"}.get(c["mode"], "3-D grid")
    share = f" ({100 * c['free'] / c['reached']:.1f} % of reached)" if c["reached"] else ""
    pairs = ", ".join(f"{' - '.join(p['links'])} ({p['points']:,})" for p in c["binding_pairs"])
    return "\n".join([
        f"collision check on a {grid}, step {fmt(c['step_m'], 4)} m",
        key_values([
            ("grid points searched" if searched else "grid points", f"{c['grid_points']:,}"),
            ("reached by the search" if searched else "in the kinematic workspace", f"{c['reached']:,} {what}"),
            ("collision-free", f"{c['free']:,} {what}{share}"),
            ("colliding", f"{c['colliding']:,} {what}"),
            ("binding pairs", pairs or "none"),
            ("pairs checked", str(c["pairs_checked"])),
            *([("obstacles", ", ".join(c["obstacles"]))] if c["obstacles"] else []),
        ], digits=None),
    ])


def _load_mesh(path: str) -> Any:
    """A triangle mesh file (.stl, .ply, .glb) through trimesh, or one line of bad input."""
    import os

    import trimesh

    ext = os.path.splitext(path)[1].lower()
    if ext not in (".stl", ".ply", ".glb"):
        raise InvalidInputError("--mesh", f"{path!r}: unknown suffix {ext or '(none)'!r}; use .stl, .ply or .glb")
    if not os.path.isfile(path):
        raise InvalidInputError("--mesh", f"{path!r}: no such file")
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad file
        raise InvalidInputError("--mesh", f"{path!r} is not a readable {ext[1:]} mesh: {exc}") from None
    if len(getattr(mesh, "faces", ())) == 0:
        raise InvalidInputError("--mesh", f"{path!r} holds no triangles")
    return mesh


def _parallel_checks(args: argparse.Namespace, robot: Any, mech: Any, actuators: Any) -> dict[str, Any] | None:
    """Before a scene starts: the overlay grid fits the view budget, and --position (or the
    `actuators` of --q, in rad or m) is reachable in --mode (else the answer to report, exit 1)."""
    import numpy as np

    from kinematics.sizes import MAX_VIEW_POINTS, check_points, grid_points

    if args.workspace or args.singularities:
        lo, hi = mech.bounding_box(args.limits)
        check_points("--step", grid_points(lo, hi, 0.02 if args.step is None else args.step), limit=MAX_VIEW_POINTS,
                     hint=f"{args.step or 0.02:g} m is too fine a step for a view")
    if actuators is not None and args.position is None:
        fk = mech.pose_fk(actuators)
        if fk.exists:
            return None
        return {"robot": robot.name, "q": actuators.tolist(), "position": None, "mode": "-", "reachable": False,
                "reason": fk.reason}
    if args.position is None:
        return None
    mode = mech.check_branches([mode_of(args, "---")])[0]
    m = mech.branches.index(mode)
    p = np.array(args.position, dtype=float)
    sol = mech.pose_ik(p)
    if sol.reachable[m]:
        return None
    return {"robot": robot.name, "position": p.tolist(), "mode": mode, "reachable": False,
            "reason": sol.reason or f"the limbs do not assemble in mode {mode}"}
