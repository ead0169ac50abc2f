"""`kinematics singularities`: its arguments and handler (closed forms, singular fields of closed
loops, possibly singular joint boxes of serial arms)."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from kinematics.cli.args import (
    SERIAL_BUDGET,
    Command,
    collision_args,
    collision_checks,
    load,
    positive,
    refuse_serial_args,
    robot_arg,
    scan_args,
    serial_args,
)
from kinematics.cli.report import Out, compile_notice, emit, fmt, key_values, show_progress, table
from kinematics.errors import InvalidInputError
from kinematics.sizes import check_points

if TYPE_CHECKING:
    from kinematics.mechanisms.base import Mechanism
    from kinematics.model.robot import Robot


MAX_BASE_STEP_DEG = 90.0
"""[deg] The coarsest --base-step-deg: a quarter turn (the turn is first cut into 16 intervals of
22.5 deg, so any step from 22.5 deg up certifies on those alone)."""


def base_step_deg(text: str) -> float:
    """--base-step-deg: a finite angle in (0, MAX_BASE_STEP_DEG] degrees."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of degrees, got {text!r}") from None
    if not (math.isfinite(v) and 0 < v <= MAX_BASE_STEP_DEG):
        raise argparse.ArgumentTypeError(f"must be in (0, {MAX_BASE_STEP_DEG:g}] degrees, got {text}")
    return v


def register(command: Command) -> None:
    p = command("singularities", cmd_singularities,
                "type I/II/III singular loci over a grid (p2us, delta, any closed loop); theta2 = 0 boundary "
                "(planar arm); possibly singular joint boxes (serial arms)")
    robot_arg(p)
    scan_args(p, 0.01)
    p.add_argument("--paper-scan", action="store_true", help="p2us: also paper B's 8x8x8 actuator scan")
    p.add_argument("--angle-step-deg", type=positive, default=None, metavar="DEG",
                   help="planar arm: joint-grid step in degrees (default 1)")
    p.add_argument("--base-step-deg", type=base_step_deg, default=None, metavar="DEG",
                   help="serial arms with --collisions/--obstacles: the finest base-angle interval [deg] of the "
                        "certified collision-free base angles, where the base's angle matters (else unused, with a warning; default 1; in (0, "
                        f"{MAX_BASE_STEP_DEG:g}]; --json key collisions.base_angle_step_rad)")
    serial_args(p)
    collision_args(p, "; flags the singular points inside the workspace whose configuration collides "
                      "(p2us, delta, the planar arm, closed loops with singular fields; serial arms: each listed joint "
                      "box at its centre, with the base angles at which it is free where that angle matters)")


def cmd_singularities(args: argparse.Namespace) -> int:
    """Singular loci over a grid (p2us) or the joint grid (planar arm)."""
    return singularities(args, load(args), emit)


def serial_scan(args: argparse.Namespace, robot: Robot) -> Any:
    """`serial_workspace` with the CLI's --resolution, --max-points and --rtol (0: 0.02)."""
    from kinematics.analyses.serial_workspace import serial_workspace

    if getattr(args, "modes", None):
        raise InvalidInputError("--modes", "working modes are for the 3-[P2(US)] and the planar arm")
    if getattr(args, "limits", "all") != "all":
        raise InvalidInputError("--limits", "a serial arm has its URDF's joint limits only: use all")
    if getattr(args, "plot", None):
        raise InvalidInputError("--plot", "no figure for serial arms yet; use `show ROBOT --workspace --export F.html`")
    if args.max_points is None:
        args.max_points = SERIAL_BUDGET
    if args.max_points < 1000:  # before check_points, whose floor (1) is not this one
        raise InvalidInputError("--max-points", f"must be at least 1000, got {args.max_points:g}")
    budget = args.max_points = check_points("--max-points", args.max_points, hint="a smaller budget")
    if args.resolution is not None:
        if args.resolution < 4:
            raise InvalidInputError("--resolution", f"must be at least 4 cells, got {args.resolution}")
        check_points("--resolution", float(args.resolution) ** 3, hint="fewer cells across")
    rtol = getattr(args, "rtol", 0.0) or 0.02
    return serial_workspace(robot, rtol=rtol, resolution=args.resolution, max_points=budget,
                            progress=show_progress(args))


def singular_sample(ws: Any, robot: Robot, count: int = 200) -> list[dict[str, Any]]:
    """An evenly spaced sample of the possibly singular boxes: the world position [m] of the
    frame at the box's centre (the base joint at its listed value for a solid of revolution), the
    ball radius [m] the box's image lies within, the joint values of the centre and its
    half-widths [rad or m]."""
    import numpy as np

    from kinematics.generic.batched import BatchedKinematics, configurations

    k = len(ws.singular_radius)
    idx = np.unique(np.linspace(0, k - 1, min(k, count)).astype(int)) if k else np.zeros(0, dtype=int)
    q = ws.singular_configurations[idx]
    # the centre's own position (a revolved scan's profile points carry no azimuth)
    world = (BatchedKinematics.from_robot(robot, ws.frame).fk(configurations(robot, q)).position if len(idx)
             else np.zeros((0, 3)))
    half = (ws.singular_half_widths[idx] if ws.singular_half_widths is not None else np.full(q.shape, np.nan))
    return [{"position": p.tolist(), "radius_m": float(r), "q": c.tolist(), "half_width": w.tolist()}
            for p, r, c, w in zip(world, ws.singular_radius[idx], q, half, strict=True)]


def _serial_singularities(args: argparse.Namespace, robot: Robot, out: Out, checks: Any = None) -> int:
    ws = serial_scan(args, robot)
    sample = singular_sample(ws, robot)
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
        "budget_exhausted": ws.unsplit > 0, "unsplit_boxes": ws.unsplit, "unsplit_radius_m": ws.unsplit_radius,
        "leaf_radius_m": ws.leaf_radius,
        "seconds": ws.seconds,
    }
    if checks is not None:
        _flag_serial(payload, robot, ws, checks, None if args.base_step_deg is None else math.radians(args.base_step_deg))

    def human() -> str:
        rad = payload["radius_m"]
        shown = sample[:: max(1, len(sample) // 10)]
        rows = [(fmt(p["position"], 4), fmt(p["radius_m"], 3), *([_serial_collision_cell(p)] if checks else []))
                for p in shown]
        return "\n".join([
            f"{robot.name}: joint boxes of frame {ws.frame} that may hold a rank-deficient position Jacobian",
            key_values([
                ("possibly singular boxes", f"{len(r):,}"),
                ("image radius [m]", f"{fmt(rad['min'], 3)} .. {fmt(rad['max'], 3)}" if rad else "-"),
                ("configurations evaluated", f"{ws.points_evaluated:,} of a {args.max_points:,} budget"),
                ("budget", _budget_line(ws)),
                ("time [s]", f"{ws.seconds:.2f}"),
            ], digits=None),
            "tolerance: " + payload["tolerance"],
            *([_serial_collision_line(payload["collisions"])] if checks is not None else []),
            "",
            table(["position [m] (sample)", "radius [m]", *(["collisions (centre)"] if checks else [])], rows)
            if rows else "no singular box",
        ])

    out(args, payload, human)
    return 0


def _budget_line(ws: Any) -> str:
    """Whether the budget finished every box, or how coarse it left the listed balls."""
    if not ws.unsplit:
        return f"sufficed: every box finished (image radius <= {fmt(ws.leaf_radius, 3)} m) or settled inside"
    return (f"exhausted: {ws.unsplit:,} boxes left unsplit, image radius up to {fmt(ws.unsplit_radius, 3)} m "
            f"(a finished box's: {fmt(ws.leaf_radius, 3)} m); the balls still hold every singular image, "
            "only that coarsely (raise --max-points)")


def joint_singular_points(sing: dict[str, Any]) -> list[dict[str, Any]]:
    """JSON-ready points of a joint-space singular set (`Mechanism.joint_singularities`)."""
    return [{"position": p.tolist(), "q": q.tolist(), "type": "theta2 = 0"}
            for p, q in zip(sing["singular_points"], sing["singular_q"], strict=True)]


def singularities(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    compile_notice(args, mech.kernels())
    checks = collision_checks(args, robot)
    serial = not ({"joint_singularities", "singular_fields"} & mech.capabilities)
    if args.base_step_deg is not None and (checks is None or not serial):
        raise InvalidInputError("--base-step-deg", "is for serial arms with --collisions or --obstacles")
    if args.angle_step_deg is not None and "joint_singularities" not in mech.capabilities:  # else ignored
        raise InvalidInputError("--angle-step-deg", "is for a planar arm's joint grid (scara); this robot's scan "
                                "is on task-space points (--step) or joint boxes (--max-points)")
    if serial:
        # an open chain without closed forms: its joint boxes that may hold a rank-deficient
        # position Jacobian (the cell engine's Lipschitz test, a guarantee no sampling gives)
        return _serial_singularities(args, robot, out, checks)
    refuse_serial_args(args, "this robot's singular loci are scanned on task-space points (--step)")
    if "joint_singularities" in mech.capabilities:
        mech.check_branches(args.modes or None)  # the singular set is every branch's; a typo is still bad input
        s = mech.joint_singularities(math.radians(args.angle_step_deg or 1.0))
        pts = joint_singular_points(s)
        payload = {
            "robot": robot.name,
            "singular_points": pts,
            "theta2_zero_within_limits": s["theta2_zero_within_limits"],
            "theta2_pi_within_limits": s["theta2_pi_within_limits"],
            "min_radius": {"min": float(s["min_radius"].min()), "max": float(s["min_radius"].max())},
            "grid": [len(s["theta1"]), len(s["theta2"])],
        }
        if checks is not None:
            _flag_colliding_configurations(payload, robot, checks, s["singular_q"])
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
                    *([("colliding singular configurations",
                        f"{payload['collisions']['colliding_points']} of {len(pts)}")] if checks is not None else []),
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


def _flag_colliding_configurations(payload: dict[str, Any], robot: Robot, checks: Any, values: Any) -> None:
    """Mark each listed singular point `colliding` where its configuration (joint values `values`,
    one row per point) brings some checked pair to a negative signed distance, and add the counts."""
    import numpy as np

    from kinematics.analyses.collisions import summary

    q = np.array([robot.configuration(v) for v in np.asarray(values, dtype=float)]).reshape(len(values), -1)
    depth, pair = checks.margin(q) if len(q) else (np.zeros(0), np.zeros(0, dtype=int))
    flags = depth < 0
    for item, flag, k in zip(payload["singular_points"], flags, pair, strict=True):
        item["colliding"] = bool(flag)
        if flag:
            item["pair"] = list(checks.pair_links[int(k)])
    payload["collisions"] = {**summary(checks), "singular_points": len(flags), "colliding_points": int(flags.sum()),
                             "any_collision_free": bool((~flags).any())}


def _flag_serial(payload: dict[str, Any], robot: Robot, ws: Any, checks: Any, step: float | None) -> None:
    """Mark each listed singular box `colliding` at its centre as listed (with the binding `pair`)
    and, where the base's angle changes some pair's distance, with its certified free base angles,
    bisected down to intervals `step` [rad] wide (None: the library's STEP) (`analyses.serial_singular_collisions`);
    add the counts."""
    import numpy as np

    from kinematics.analyses.collisions import summary
    from kinematics.analyses.serial_singular_collisions import STEP, singular_collisions

    pts = payload["singular_points"]
    shape = (len(pts), robot.nv)
    res = singular_collisions(robot, ws, checks, np.array([p["q"] for p in pts]).reshape(shape),
                              np.array([p["half_width"] for p in pts]).reshape(shape), STEP if step is None else step)
    if step is not None and res.base_angle != "varies":
        import sys

        print(f"warning: --base-step-deg unused: the base angle {_UNUSED[res.base_angle]}", file=sys.stderr)
    widths = res.free_measure()
    for k, item in enumerate(pts):
        item["colliding"] = bool(res.colliding[k])
        item["box_free"] = bool(res.box_free[k])
        if res.colliding[k]:
            item["pair"] = list(checks.pair_links[int(res.pair[k])])
        if res.base_angle == "varies":
            f = res.free_intervals[k]
            item["base_angles"] = {"free": str(res.verdict[k]), "free_rad": float(widths[k]),
                                   "free_intervals": f.tolist(), "free_samples": int(res.free_samples[k]),
                                   "samples": int(res.samples[k]),
                                   "colliding_samples": int(res.colliding_samples[k])}
    c = {**summary(checks), "singular_points": len(pts), "colliding_points": int(res.colliding.sum()),
         "boxes_certified_free": int(res.box_free.sum()), "base_angle": res.base_angle,
         "verdict": _VERDICT[res.base_angle] + _BOX}
    if res.base_angle == "varies":
        v = res.verdict
        c.update(base_joint=robot.dofs[res.base_joint].name, base_angle_step_rad=res.step,
                 free_at_every_base_angle=int((v == "every").sum()), free_at_some_base_angle=int((v == "some").sum()),
                 free_at_no_base_angle=int(np.isin(v, ["none", "none found"]).sum()),
                 any_collision_free=bool(np.isin(v, ["every", "some"]).any()))
    else:
        c["any_collision_free"] = bool((~res.colliding).any())
    payload["collisions"] = c


_BOX = ("; box_free: the whole box certified collision-free (at the listed base angle) by the distances' "
        "Lipschitz bound in the joints")

_VERDICT = {
    "invariant": "each box judged at its centre (the box's other configurations unchecked: half_width beside); "
                 "every checked pair turns with the base or not at all, so the verdict holds at every base angle",
    "varies": "each box judged at its centre (the box's other configurations unchecked: half_width beside); "
              "colliding: at the listed base angle; base_angles.free_intervals: base-joint values certified "
              "collision-free by the distances' Lipschitz bound in the base angle (every, some, none found at "
              "the step, none: a pair the base's turn leaves alone collides)",
    "in the configuration": "each box judged at its centre, every joint as listed (the box's other configurations "
                            "unchecked: half_width beside)",
}


_UNUSED = {"invariant": "changes no checked pair's distance (every verdict holds at every base angle)",
           "in the configuration": "is one of the scan's box joints (a base turning less than a full turn, or "
                                   "a planar or spatial scan): each verdict is at the listed configuration"}

_BASE_ANGLES = {"every": "every base angle", "some": "some base angles", "none": "no base angle",
                "none found": "no base angle found"}


def _serial_collision_cell(point: dict[str, Any]) -> str:
    """One listed box's collision verdict for the human table: colliding (its pair) or free at the
    listed angle, the free base angles where the turn matters, and a whole box certified free."""
    cell = f"colliding ({' - '.join(point['pair'])})" if point["colliding"] else "free"
    if "base_angles" in point:
        cell += "; free at " + _BASE_ANGLES[point["base_angles"]["free"]]
    return cell + ("; whole box free" if point["box_free"] else "")


def _serial_collision_line(c: dict[str, Any]) -> str:
    line = f"colliding singular configurations: {c['colliding_points']} of {c['singular_points']} (box centres"
    boxes = f"; whole boxes certified free: {c['boxes_certified_free']}"
    if c["base_angle"] == "varies":
        return (f"{line}, base at the listed angle); free at every base angle {c['free_at_every_base_angle']}, "
                f"at some {c['free_at_some_base_angle']}, at none found {c['free_at_no_base_angle']} (base-angle "
                f"step {math.degrees(c['base_angle_step_rad']):.4g} deg){boxes}")
    return line + (", at every base angle)" if c["base_angle"] == "invariant" else ")") + boxes
