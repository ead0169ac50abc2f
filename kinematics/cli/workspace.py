"""`kinematics workspace-volume`, `singularities` and `sweep`: their arguments and handlers."""

from __future__ import annotations

import argparse
import math
import os
import time
from typing import TYPE_CHECKING, Any

from kinematics.cli.args import (
    Command,
    collision_args,
    collision_checks,
    integer,
    load,
    non_negative,
    orientation_args,
    orientation_of,
    positive,
    robot_arg,
    scan_args,
    serial_args,
)
from kinematics.cli.report import Out, emit, fmt, key_values, show_progress, table
from kinematics.errors import InvalidInputError
from kinematics.files import write_atomic
from kinematics.sizes import MAX_LISTED_POINTS, check_points, grid_points

if TYPE_CHECKING:
    import numpy as np

    from kinematics.mechanisms.base import Mechanism
    from kinematics.model.robot import Robot


def register(command: Command) -> None:
    p = command("workspace-volume", cmd_workspace_volume,
                "workspace volume (p2us, delta, closed loops, serial arms) or area (planar arms and loops) with its "
                "error estimate, per mode, with singular points")
    robot_arg(p)
    scan_args(p, 0.01)
    p.add_argument("--rtol", type=non_negative, default=1e-3, metavar="R",
                   help="relative tolerance on the volume's error estimate; the quadrature refines until it "
                        "is met (default 1e-3; 0: 1e-2)")
    p.add_argument("--points", metavar="FILE", help="write the grid points inside the workspace (.npy or CSV)")
    collision_args(p, "; reports the binding pairs and the volume each removes (p2us, delta, scara, closed loops)")
    orientation_args(p, "the volume of tool positions reachable")

    p = command("singularities", cmd_singularities,
                "type I/II/III singular loci over a grid (p2us, delta, any closed loop); theta2 = 0 boundary "
                "(planar arm); possibly singular joint boxes (serial arms)")
    robot_arg(p)
    scan_args(p, 0.01)
    p.add_argument("--paper-scan", action="store_true", help="p2us: also paper B's 8x8x8 actuator scan")
    p.add_argument("--angle-step-deg", type=positive, default=1.0, metavar="DEG",
                   help="planar arm: joint-grid step in degrees (default 1)")
    serial_args(p)
    collision_args(p, "; flags the singular points inside the workspace whose configuration collides "
                      "(p2us, delta, closed loops with singular fields)")

    p = command("sweep", cmd_sweep, "design sweep of the 3-[P2(US)] on Dask: volume, singularity-free "
                                     "fraction, conditioning")
    robot_arg(p)
    p.add_argument("--param", action="append", metavar="NAME=START:STOP:COUNT",
                   help="a swept parameter (repeatable): b, d, L, beta, theta_zero, rod_spacing, stroke_min, "
                        "stroke_max [m, rad]")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running dask scheduler (default: an embedded "
                                                            "local cluster)")
    p.add_argument("--workers", type=integer, metavar="N",
                   help="worker processes of the local cluster, 1 to 4 per core (default: cores)")
    p.add_argument("--step", type=positive, default=0.02, metavar="M", help="grid step per design [m] (default 0.02)")
    p.add_argument("--rtol", type=positive, default=1e-2, metavar="R", help="volume tolerance (default 1e-2)")
    p.add_argument("--out", metavar="FILE.csv", help="write the table as CSV")
    collision_args(p, "; adds each design's collision-free volume (its URDF generated with the robot's "
                      "collision sizes)")


def cmd_workspace_volume(args: argparse.Namespace) -> int:
    """Workspace volume (area) with bounds, per mode and union, and the singular points in it."""
    return workspace_volume(args, load(args), emit)


def cmd_singularities(args: argparse.Namespace) -> int:
    """Singular loci over a grid (p2us) or the joint grid (planar arm)."""
    return singularities(args, load(args), emit)


def cmd_sweep(args: argparse.Namespace) -> int:
    """Design sweep of the 3-[P2(US)] on Dask."""
    return sweep(args, load(args), emit)


def serial_scan(args: argparse.Namespace, robot: Robot) -> Any:
    """`serial_workspace` with the CLI's --resolution, --max-points and --rtol (0: 0.02)."""
    from kinematics.analyses.serial_workspace import serial_workspace

    if getattr(args, "modes", None):
        raise InvalidInputError("--modes", "working modes are for the 3-[P2(US)] and the planar arm")
    if getattr(args, "limits", "all") != "all":
        raise InvalidInputError("--limits", "a serial arm has its URDF's joint limits only: use all")
    if getattr(args, "plot", None):
        raise InvalidInputError("--plot", "no figure for serial arms yet; use `show ROBOT --workspace --export F.html`")
    budget = args.max_points = check_points("--max-points", args.max_points, hint="a smaller budget")
    if budget < 1000:
        raise InvalidInputError("--max-points", f"must be at least 1000, got {budget}")
    if args.resolution is not None:
        if args.resolution < 4:
            raise InvalidInputError("--resolution", f"must be at least 4 cells, got {args.resolution}")
        check_points("--resolution", float(args.resolution) ** 3, hint="fewer cells across")
    rtol = getattr(args, "rtol", 0.0) or 0.02
    return serial_workspace(robot, rtol=rtol, resolution=args.resolution, max_points=budget,
                            progress=show_progress(args))


def singular_sample(ws: Any, count: int = 200) -> list[dict[str, Any]]:
    """An evenly spaced sample of the possibly singular boxes: world position [m] (the base joint
    at 0 for a solid of revolution), the ball radius [m] their image lies within, the joint values."""
    import dataclasses

    import numpy as np

    k = len(ws.singular_radius)
    idx = np.unique(np.linspace(0, k - 1, min(k, count)).astype(int)) if k else np.zeros(0, dtype=int)
    world = dataclasses.replace(ws, singular_points=ws.singular_points[idx]).world_points("singular", turns=1)
    return [{"position": p.tolist(), "radius_m": float(r), "q": q.tolist()}
            for p, r, q in zip(world, ws.singular_radius[idx], ws.singular_configurations[idx], strict=True)]


def _serial_singularities(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    ws = serial_scan(args, robot)
    sample = singular_sample(ws)
    r = ws.singular_radius
    payload = {
        "robot": robot.name, "frame": ws.frame, "mode": ws.mode,
        "singular_boxes": len(r),
        "tolerance": "a joint box counts when sigma_min(J(centre)) <= sum_i d_i |dJ/dq_i| (its own Lipschitz "
                     "bound, no chosen threshold); every rank-deficient configuration's image lies within "
                     "radius_m of a listed point",
        "radius_m": {"min": float(r.min()), "max": float(r.max())} if len(r) else None,
        "singular_points": sample,
        "points_evaluated": ws.points_evaluated, "max_points": args.max_points, "cell_m": ws.grid.cell,
        "seconds": ws.seconds,
    }

    def human() -> str:
        rad = payload["radius_m"]
        rows = [(fmt(p["position"], 4), fmt(p["radius_m"], 3)) for p in sample[:: max(1, len(sample) // 10)]]
        return "\n".join([
            f"{robot.name}: joint boxes of frame {ws.frame} that may hold a rank-deficient position Jacobian",
            key_values([
                ("possibly singular boxes", f"{len(r):,}"),
                ("image radius [m]", f"{fmt(rad['min'], 3)} .. {fmt(rad['max'], 3)}" if rad else "-"),
                ("configurations evaluated", f"{ws.points_evaluated:,} of a {args.max_points:,} budget"),
                ("time [s]", f"{ws.seconds:.2f}"),
            ], digits=None),
            "tolerance: " + payload["tolerance"],
            "",
            table(["position [m] (sample)", "radius [m]"], rows) if rows else "no singular box",
        ])

    out(args, payload, human)
    return 0


def _write_points(path: str, points: np.ndarray, header: str) -> None:
    """Write points as .npy or CSV (by suffix), atomically."""
    import numpy as np

    if os.path.splitext(path)[1].lower() == ".npy":
        write_atomic(path, lambda tmp: np.save(tmp, points), "--points")
    else:
        write_atomic(path, lambda tmp: np.savetxt(tmp, points, delimiter=",", header=header, comments="",
                                                  fmt="%.17g"), "--points")


def _inside_points(mech: Mechanism, limits: str, step: float, branches: tuple[str, ...], margin: Any = None
                   ) -> np.ndarray:
    """Grid points (cell centres at `step`) inside the union (of `margin`'s last column, default
    the mechanism's margin), for --points."""
    import numpy as np

    lo, hi = mech.bounding_box(limits)
    margin = mech.margin(branches, limits) if margin is None else margin
    check_points("--points", grid_points(lo, hi, step), limit=MAX_LISTED_POINTS,
                 hint=f"{step:g} m is too fine a step to list the points")
    axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(len(lo))]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(lo))
    return pts[margin(pts)[:, -1] >= 0]


def workspace_volume(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    orientation = orientation_of(args)
    if orientation is not None:
        from kinematics.mechanisms.serial.mechanism import with_fixed_orientation

        if getattr(args, "collisions", False) or getattr(args, "obstacles", None):
            raise InvalidInputError("--collisions/--obstacles", "not available with a fixed tool orientation yet")
        mech = with_fixed_orientation(robot, orientation)
    mech.require("margin", "workspace-volume")
    mech.check_limits(args.limits)
    kernels = mech.kernels()
    if kernels and show_progress(args):  # a terminal's notice, like the progress bars
        from kinematics import jit

        if not jit.cached(kernels):
            import sys

            print("compiling kernels (first run only)", file=sys.stderr, flush=True)
    # (a generic closed loop compiles its solver here: its branches come from an atlas search)
    branches = mech.check_branches(args.modes or None)
    rtol = None if args.rtol == 0 else args.rtol
    if getattr(args, "collisions", False) or getattr(args, "obstacles", None):
        return _collision_volume(args, robot, mech, branches, rtol, out)
    t0 = time.perf_counter()
    sing_summary: dict[str, Any] = {}
    singular_points: list[dict[str, Any]] = []
    sing: Any = None
    paper: dict[str, Any] = {}
    # check: a second run at half the column step; disagreement beyond the estimates -> not converged
    ws = measure_workspace(mech, step=args.step, rtol=rtol, branches=branches, limits=args.limits,
                           progress=show_progress(args), check=True)
    if "singular_fields" in mech.capabilities:
        from kinematics.analyses.singularities import singular_loci

        sing = singular_loci(mech, step=args.step, limits=args.limits, branches=branches,
                             progress=show_progress(args))
        sing_summary = sing.summary()
        singular_points = sing.locus.as_list()
    elif "joint_singularities" in mech.capabilities:
        sing = mech.joint_singularities()
        singular_points = _joint_singular_points(sing)
        sing_summary = {"theta2_zero": {"locus_points": len(singular_points),
                                        "within_limits": sing["theta2_zero_within_limits"]}}
    if "reference_results" in mech.capabilities:
        r = ws.result
        per_mode = {name: float(r.estimate[k]) for k, name in enumerate(ws.targets[:-1])}
        paper = mech.reference_results(str(robot.urdf_path), args.limits, per_mode, ws.total)
    if args.points:
        pts = _inside_points(mech, args.limits, args.step, branches)
        _write_points(args.points, pts, ",".join(mech.task_axes))
    if args.plot:
        from kinematics.views import plots

        plots.headless()
        fig = (plots.scara_workspace(mech.params, sing) if "joint_singularities" in mech.capabilities
               else plots.spatial_workspace(mech, args.limits, max(args.step, 0.01),
                                            singular=sing.locus if sing is not None else None))
        plots.save(fig, args.plot)
    payload = ws.as_dict()
    payload.update(family=mech.family, singular_points=singular_points, singularities=sing_summary,
                   orientation=None if orientation is None else orientation.as_dict(),
                   seconds=time.perf_counter() - t0, volume_seconds=ws.seconds, **paper)
    if kernels:
        from kinematics import jit

        payload["compiled_kernels"] = jit.compiled(kernels)
    if not ws.result.converged:
        import sys

        print(f"warning: {_not_converged(ws)}", file=sys.stderr)

    def human() -> str:
        exact = getattr(mech.margin(branches, args.limits), "exact_columns", None)
        return _report(ws, payload, paper, mech,
                       None if exact is None else getattr(exact, "method", "roots of quadratics"))

    out(args, payload, human)
    return 0


def _collision_volume(args: argparse.Namespace, robot: Robot, mech: Mechanism, branches: tuple[str, ...],
                      rtol: float | None, out: Out) -> int:
    """`workspace-volume --collisions` / `--obstacles`: the collision-free volume per branch and
    union, the kinematic union and what each binding pair removes (`analyses.collisions`)."""
    from kinematics.analyses.collisions import margin_builder, measure_collision_workspace

    if args.plot:
        raise InvalidInputError("--plot", "not available with --collisions or --obstacles yet")
    checks = collision_checks(args, robot)
    cw = measure_collision_workspace(mech, robot, step=args.step, rtol=rtol, branches=branches, limits=args.limits,
                                     progress=show_progress(args), collision_model=checks)
    if args.points:  # the collision-aware union: CollisionMargin's last column
        pts = _inside_points(mech, args.limits, args.step, branches, margin_builder(mech, robot, checks, args.limits)(branches))
        _write_points(args.points, pts, ",".join(mech.task_axes))
    ws = cw.workspace
    payload = cw.as_dict()
    payload.update(family=mech.family)
    if not ws.result.converged:
        import sys

        print(f"warning: {_not_converged(ws)}", file=sys.stderr)

    def human() -> str:
        unit, key = ("m^2", "area") if ws.planar else ("m^3", "volume")
        rows = [(f"{a} - {b}", f"{fmt(p.removed, 4)} +/- {fmt(p.error, 2)}", str(p.prescan_points))
                for p in cw.pairs for a, b in [p.links]]
        return "\n".join([
            f"{robot.name}: collision-free {key} ({', '.join(branches)}; limits {args.limits})",
            key_values([
                (f"{key} [{unit}]", (f"{fmt(ws.total, 6)} +/- {fmt(ws.error, 2)} "
                                     f"({'converged' if ws.result.converged else 'NOT converged'})")),
                (f"kinematic {key} [{unit}]", f"{fmt(cw.kinematic, 6)} +/- {fmt(cw.kinematic_error, 2)}"),
                (f"removed by collisions [{unit}]", fmt(cw.removed, 4)),
                ("pairs checked", str(payload["collisions"]["pairs_checked"])),
                *([("obstacles", ", ".join(payload["collisions"]["obstacles"]))] if args.obstacles else []),
                ("time [s]", f"{ws.seconds:.2f}"),
            ], digits=None),
            "",
            table(["binding pair", f"removes alone [{unit}]", "pre-scan points"], rows) if rows
            else "no pair binds (on the pre-scan grid)",
        ])

    out(args, payload, human)
    return 0


_LENGTHS = {"b", "d", "L", "rod_spacing", "stroke", "l1", "l2"}
_ANGLES = {"beta", "alpha", "theta_limits", "phi_limits", "theta_zero", "lower", "upper"}


def _parameter_rows(parameters: dict[str, Any]) -> list[tuple[str, str]]:
    """(name [unit], value) rows: lengths in m, angles shown in degrees."""
    rows = []
    for k, v in parameters.items():
        if k in _ANGLES:
            deg = [math.degrees(x) for x in v] if isinstance(v, (list, tuple)) else math.degrees(v)
            rows.append((f"{k} [deg]", fmt(deg, 6)))
        else:
            rows.append((f"{k} [m]" if k in _LENGTHS else k, fmt(v, 6)))
    return rows


def _not_converged(ws: Any) -> str:
    """Why a measurement did not converge, naming the targets whose own estimate failed."""
    failed = ws.unconverged()
    if not failed:
        return ("the volume did not converge (the evaluation budget ran out, or nothing was found inside); "
                "try a larger --step or check the limits")
    by_reason: dict[str, list[str]] = {}
    for name, why in failed.items():
        by_reason.setdefault(why, []).append(name)
    detail = "; ".join(f"{', '.join(names)}: {why}" for why, names in by_reason.items())
    if ws.targets[-1] not in failed:
        advice = "the union converged; try a smaller --step, or leave those branches out with --modes"
    elif ws.fixed_error_binds()[-1]:
        advice = "a smaller --step cannot help; the estimate and its error are the answer at this --rtol"
    else:
        advice = "try a smaller --step"
    return f"not converged on {len(failed)} of {len(ws.targets)} targets ({detail}); {advice}"


def _report(ws: Any, payload: dict[str, Any], paper: dict[str, Any], mech: Mechanism, exact: str | None) -> str:
    """The human report; `exact`: how the margin's exact columns find their ends (None: sampled)."""
    unit = "m^2" if ws.planar else "m^3"
    key = "area" if ws.planar else "volume"
    r = ws.result
    rows = [(name, r.estimate[k], r.error[k]) for k, name in enumerate(ws.targets)]
    lines = []
    if payload.get("compiled_kernels"):
        lines += ["(compiled the Numba kernels: first run only)"]
    held = payload.get("orientation")
    lines += [f"{ws.robot}: workspace {key} ({ws.limits} limits"
              + (f"; tool held at {held['text']})" if held else ")"), ""]
    lines.append(key_values(_parameter_rows({k: v for k, v in ws.parameters.items() if k != "orientation"}),
                            digits=None))
    lines += ["", table([mech.branch_kind, f"{key} [{unit}]", f"error estimate [{unit}]"], rows),
              mech.branch_legend, ""]
    lo, hi = payload["bbox"]
    rel = ws.error / ws.total if ws.total > 0 else math.inf
    lines.append(key_values([
        (f"{key} [{unit}]", (f"{fmt(ws.total, 8)} +/- {fmt(ws.error, 2)} (estimated error, {fmt(rel, 2)} relative; "
                            f"rtol {fmt(r.rtol, 2)}; {'converged' if r.converged else 'NOT converged'})")),
        ("method", ("cell refinement" if payload.get("method") != "columns" else
                    f"sampled columns (roots to {fmt(getattr(r, 'root_tol', 0.0), 2)} m) + adaptive Gauss quadrature; "
                    "inside intervals or gaps "
                    f"shorter than the column step {fmt(r.step)} m can be missed" if ws.planar or exact is None else
                    f"exact columns ({exact}) + Gauss rules between located breaks; a feature narrower "
                    f"than the node spacing {fmt(r.step)} m across columns can be missed")),
        *([("not converged", _not_converged(ws))] if not r.converged else []),
        ("bounding box of inside samples [m]", f"{[round(x, 4) for x in lo]} .. {[round(x, 4) for x in hi]}"),
        ("points evaluated", f"{r.points_evaluated:,}"),
        ("singular points inside", len(payload["singular_points"])),
        ("singular loci", "; ".join(f"{k} " + ", ".join(f"{a.replace('_', ' ')} {b}" for a, b in v.items())
                                    for k, v in payload["singularities"].items())),
        ("time [s]", f"{payload['seconds']:.2f} (volume {payload['volume_seconds']:.2f})"),
    ], digits=None))
    if paper:
        lines += ["", *mech.reference_lines(paper)]
    return "\n".join(lines)


def _joint_singular_points(sing: dict[str, Any]) -> list[dict[str, Any]]:
    """JSON-ready points of a joint-space singular set (`Mechanism.joint_singularities`)."""
    return [{"position": p.tolist(), "q": q.tolist(), "type": "theta2 = 0"}
            for p, q in zip(sing["singular_points"], sing["singular_q"], strict=True)]


def singularities(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    checks = collision_checks(args, robot)
    if checks is not None and "singular_fields" not in mech.capabilities:
        raise InvalidInputError("--collisions/--obstacles", f"{mech.family} singularities are not collision-aware "
                                "yet (p2us, delta and closed loops with singular fields are)")
    if not ({"joint_singularities", "singular_fields"} & mech.capabilities):
        # an open chain without closed forms: its joint boxes that may hold a rank-deficient
        # position Jacobian (the cell engine's Lipschitz test, a guarantee no sampling gives)
        return _serial_singularities(args, robot, out)
    if "joint_singularities" in mech.capabilities:
        mech.check_branches(args.modes or None)  # the singular set is every branch's; a typo is still bad input
        s = mech.joint_singularities(math.radians(args.angle_step_deg))
        pts = _joint_singular_points(s)
        payload = {
            "robot": robot.name,
            "singular_points": pts,
            "theta2_zero_within_limits": s["theta2_zero_within_limits"],
            "theta2_pi_within_limits": s["theta2_pi_within_limits"],
            "min_radius": {"min": float(s["min_radius"].min()), "max": float(s["min_radius"].max())},
            "grid": [len(s["theta1"]), len(s["theta2"])],
        }
        if args.plot:
            from kinematics.views import plots

            plots.headless()
            plots.save(plots.scara_workspace(mech.params, s), args.plot)

        def human() -> str:
            return "\n".join([
                f"{robot.name}: det J = l1 l2 sin(theta2) = 0 at theta2 = 0 (stretched) and theta2 = +/-pi (folded)",
                key_values([
                    ("theta2 = 0 within limits", payload["theta2_zero_within_limits"]),
                    ("theta2 = pi within limits", payload["theta2_pi_within_limits"]),
                    ("singular points found", len(pts)),
                    ("joint grid", f"{payload['grid'][0]} x {payload['grid'][1]}"),
                    ("smallest radius [m]", f"{fmt(payload['min_radius']['min'])} .. {fmt(payload['min_radius']['max'])}"),
                ], digits=None),
            ])

        out(args, payload, human)
        return 0
    from kinematics.analyses.singularities import singular_loci

    mech.require("singular_fields", "singularities")
    if args.paper_scan:
        mech.require("paper_scan", "--paper-scan (paper B's 512-point scan of the 3-[P2(US)])")
    res = singular_loci(mech, step=args.step, limits=args.limits, branches=args.modes or None,
                        progress=show_progress(args))
    payload = {
        "robot": robot.name,
        "limits": args.limits,
        "step_m": args.step,
        "points_evaluated": res.points_evaluated,
        "singularities": res.summary(),
        "singular_points": res.locus.as_list(),
        "any_inside_workspace": res.any_inside,
        "seconds": res.seconds,
    }
    if checks is not None:
        _flag_colliding(payload, res.locus, mech, robot, checks, args.limits)
    if args.paper_scan:
        ps = mech.paper_scan()
        payload["paper_scan"] = {k: v for k, v in ps.items() if k != "rows"}
        payload["paper_scan"]["rows"] = ps["rows"]
    if args.plot:
        from kinematics.views import plots

        plots.headless()
        plots.save(plots.p2us_singular_loci(res), args.plot)

    def p2us_human() -> str:
        rows = [(k, *v.values()) for k, v in payload["singularities"].items()]
        lines = [
            (f"{robot.name}: singular loci on a {args.step:g} m grid ({args.limits} limits), "
            f"{res.points_evaluated:,} points in {res.seconds:.2f} s"),
            "",
            table(["type", "locus points", "in the workspace (type I: on its boundary)"], rows),
            "",
            ("Type I points lie on reach boundaries, so at best on the workspace's boundary; type II/III"
            " count as inside only with both grid neighbours inside the workspace."),
            f"any singular point in the workspace: {res.any_inside}",
        ]
        if checks is not None:
            c = payload["collisions"]
            lines.append(f"of those, colliding: {c['colliding_points']} of {c['interior_points']}; any in the "
                         f"collision-free workspace: {c['any_inside_collision_free']}")
        if args.paper_scan:
            ps = payload["paper_scan"]
            lines += ["", (f"paper B's scan: {ps['actuator_triples']} actuator triples -> {ps['poses']} poses "
                          f"(both assembly modes), tolerance {ps['tolerance']:g}"),
                      table(["type", "poses", "within limits"],
                            [(k, v["all"], v["within_limits"]) for k, v in ps["counts"].items()]),
                      f"smallest iota_I {fmt(ps['min_iota_I'])}, iota_II {fmt(ps['min_iota_II'])}"]
        return "\n".join(lines)

    out(args, payload, p2us_human)
    return 0


def _flag_colliding(payload: dict[str, Any], locus: Any, mech: Mechanism, robot: Robot, checks: Any,
                    limits: str) -> None:
    """Mark each listed (interior type II/III) singular point `colliding` and add the counts."""
    import numpy as np

    from kinematics.analyses.collisions import colliding_at, summary

    idx = np.flatnonzero(locus.interior)
    flags = colliding_at(mech, robot, checks, locus.points[idx], locus.which[idx], limits)
    for item, flag in zip(payload["singular_points"], flags, strict=True):
        item["colliding"] = bool(flag)
    payload["collisions"] = {**summary(checks), "interior_points": len(idx), "colliding_points": int(flags.sum()),
                             "any_inside_collision_free": bool((~flags).any())}


def sweep(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses import sweep as sw
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    mech.require("sweep_parameters", "a design sweep (of the 3-[P2(US)]'s dimensions)")
    params = mech.sweep_parameters()
    if not args.param:
        raise InvalidInputError("--param", f"give at least one, e.g. b=0.25:0.40:16; sweepable: {', '.join(sw.SWEEPABLE)}")
    axes = [sw.Axis.parse(p) for p in args.param]
    collisions = None
    if args.collisions or args.obstacles:
        from kinematics.analyses.collisions import design_options

        collisions = design_options(robot, args.collisions, args.obstacles)
    t0 = time.perf_counter()
    rows = sw.run(axes, params, step=args.step, rtol=args.rtol, scheduler=args.scheduler,
                  workers=args.workers, progress=show_progress(args), collisions=collisions)
    seconds = time.perf_counter() - t0
    text = sw.to_csv(rows)
    if args.out:
        write_atomic(args.out, text, "--out")
    payload = {"designs": rows, "columns": list(sw.columns_of(rows)), "seconds": seconds,
               "scheduler": args.scheduler or "local"}

    def human() -> str:
        shown = [c for c in sw.columns_of(rows) if c in ("design", *[a.name for a in axes]) or c not in sw.SWEEPABLE]
        return "\n".join([
            f"{len(rows)} designs on {payload['scheduler']} in {seconds:.1f} s"
            + (f"; table written to {args.out}" if args.out else ""),
            "",
            table(shown, [[r[c] for c in shown] for r in rows]),
        ])

    out(args, payload, human)
    return 0
