"""`kinematics workspace-volume`: its arguments and handler."""

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
    load,
    non_negative,
    orientation_args,
    orientation_of,
    robot_arg,
    scan_args,
)
from kinematics.cli.report import Out, compile_notice, emit, fmt, key_values, show_progress, table
from kinematics.errors import InvalidInputError
from kinematics.files import write_atomic
from kinematics.sizes import MAX_LISTED_POINTS, cell_centres, check_points, grid_points

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
    collision_args(p, "; reports the binding pairs and the volume each removes (p2us, delta, scara, closed loops, "
                      "serial arms: the best configuration their search finds, also with --orientation / --tool-axis)")
    orientation_args(p, "the volume of tool positions reachable", closed_loops=True)
    p.add_argument("--turn", choices=["auto", "envelope", "spatial"], default="auto",
                   help="serial arms with --collisions / --obstacles and a full-turn base: how pairs of a body fixed "
                        "in the world with bodies the base carries are measured: envelope (on the profile, bracketed "
                        "by the fixed body's turn envelope and by leaving its pairs out; the half-width enters the "
                        "error), spatial (in 3-D), auto (the bracket where it meets --rtol, else 3-D; default; --json "
                        "key collisions.turn)")


def cmd_workspace_volume(args: argparse.Namespace) -> int:
    """Workspace volume (area) with bounds, per mode and union, and the singular points in it."""
    return workspace_volume(args, load(args), emit)


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

    lo, hi = mech.bounding_box(limits)
    margin = mech.margin(branches, limits) if margin is None else margin
    check_points("--points", grid_points(lo, hi, step), limit=MAX_LISTED_POINTS,
                 hint=f"{step:g} m is too fine a step to list the points")
    pts = cell_centres(lo, hi, step)
    return pts[margin(pts)[:, -1] >= 0]


def workspace_volume(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.cli.singular import joint_singular_points
    from kinematics.mechanisms import mechanism_of

    orientation = orientation_of(args)
    mech = mechanism_of(robot, orientation)
    mech.require("margin", "workspace-volume")
    mech.check_limits(args.limits)
    kernels = mech.kernels()
    if kernels and "singular_fields" in mech.capabilities:  # the singular-locus scan's edge pass
        from kinematics.analyses import singular_edges

        kernels += singular_edges.kernels()
    compile_notice(args, kernels)
    colliding = getattr(args, "collisions", False) or getattr(args, "obstacles", None)
    # the collision model (or the refusal) before the branches: a generic closed loop compiles its solver to find them
    checks = collision_checks(args, robot)
    # (a generic closed loop compiles its solver here: its branches come from an atlas search)
    branches = mech.check_branches(args.modes or None)
    rtol = None if args.rtol == 0 else args.rtol
    if getattr(args, "turn", "auto") != "auto" and not (colliding and "reach_search" in mech.capabilities):
        raise InvalidInputError("--turn", "is for a serial arm's volume with --collisions or --obstacles")
    if colliding:
        return _collision_volume(args, robot, mech, branches, rtol, checks, out)
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
        singular_points = joint_singular_points(sing)
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
                                            singular=sing.locus if sing is not None else None, branches=branches))
        plots.save(fig, args.plot)
    payload = ws.as_dict()
    payload.update(family=mech.family, singular_points=singular_points, singularities=sing_summary,
                   # the mechanism's: a closed loop's 'reference' is resolved to the rotation held
                   orientation=None if orientation is None else getattr(mech, "held", orientation).as_dict(),
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
                      rtol: float | None, checks: Any, out: Out) -> int:
    """`workspace-volume --collisions` / `--obstacles`: the collision-free volume per branch and
    union, the kinematic union and what each binding pair removes (`analyses.collision_volume`)."""
    from kinematics.analyses.collision_volume import measure_collision_workspace
    from kinematics.analyses.collisions import margin_builder

    serial = "reach_search" in mech.capabilities
    if args.plot and serial:  # the figure searches every grid point at the step: checked before the volume's run
        from kinematics.sizes import MAX_COLLISION_VIEW_POINTS

        check_points("--plot", grid_points(*mech.bounding_box(args.limits), max(args.step, 0.01)),
                     limit=MAX_COLLISION_VIEW_POINTS, hint=f"a serial arm's collision-free figure at --step "
                                                           f"{args.step:g} m; use a larger --step")
    cw = measure_collision_workspace(mech, robot, step=args.step, rtol=rtol, branches=branches or None, limits=args.limits,
                                     progress=show_progress(args), collision_model=checks, turn=getattr(args, "turn", "auto"))
    margin_of = margin_builder(mech, robot, checks, args.limits)
    if args.points:  # the collision-aware union: CollisionMargin's last column
        pts = _inside_points(mech, args.limits, args.step, branches, margin_of(branches))
        _write_points(args.points, pts, ",".join(mech.task_axes))
    if args.plot:  # the chosen branches' collision-aware margins: CollisionMargin's first columns
        from kinematics.views import plots

        plots.headless()
        plots.save(plots.spatial_workspace(mech, args.limits, max(args.step, 0.01), branch_margin=margin_of(mech.branches),
                                           what="collision-free", branches=branches), args.plot)
    ws = cw.workspace
    payload = cw.as_dict()
    payload.update(family=mech.family)
    if not ws.result.converged:
        import sys

        print(f"warning: {_not_converged(ws)}", file=sys.stderr)

    held = (payload.get("parameters") or {}).get("orientation")

    def human() -> str:
        unit, key = ("m^2", "area") if ws.planar else ("m^3", "volume")
        # a link pair listed twice (two of a link's shapes bind) is told apart by its shapes
        twice = {p.links for p in cw.pairs if sum(q.links == p.links for q in cw.pairs) > 1}
        rows = [(f"{a} - {b}" + (" ({} - {})".format(*p.geometries) if p.links in twice else ""),
                 f"{fmt(p.removed, 4)} +/- {fmt(p.error, 2)}", str(p.prescan_points))
                for p in cw.pairs for a, b in [p.links]]
        return "\n".join([
            f"{robot.name}: collision-free {key} ({', '.join([*branches, f'limits {args.limits}'])})",
            key_values([
                (f"{key} [{unit}]", (f"{fmt(ws.total, 6)} +/- {fmt(ws.error, 2)} "
                                     f"({'converged' if ws.result.converged else 'NOT converged'})")),
                (f"kinematic {key} [{unit}]", f"{fmt(cw.kinematic, 6)} +/- {fmt(cw.kinematic_error, 2)}"),
                (f"removed by collisions [{unit}]", fmt(cw.removed, 4)),
                *([("zero measure", ws.measure_zero)] if ws.measure_zero else []),
                ("pairs checked", str(payload["collisions"]["pairs_checked"])),
                *([("obstacles", ", ".join(payload["collisions"]["obstacles"]))] if args.obstacles else []),
                *([("tool held at", held["text"])] if held else []),
                *([("search", _search_text(payload["collisions"]["search"]))] if "search" in payload["collisions"]
                  else []),
                *([("fixed bodies", _turn_text(payload["collisions"]["turn"], unit))]
                  if "why" in payload["collisions"].get("turn", {}) or "lower" in payload["collisions"].get("turn", {})
                  else []),
                ("time [s]", f"{ws.seconds:.2f}"),
            ], digits=None),
            "",
            table(["binding pair", f"removes alone [{unit}]", "pre-scan points"], rows) if rows
            else "no pair binds (on the pre-scan grid)",
        ])

    out(args, payload, human)
    return 0


def _search_text(search: dict[str, Any]) -> str:
    """A serial arm's search (`analyses.serial_collisions`): where it ran and its effort."""
    where = {"revolved": "on the profile (every pair unchanged by the base's turn)",
             "spatial": "in 3-D", "planar": "in the arm's plane"}.get(search["mode"], search["mode"])
    return f"{where}; {search['samples']:,} samples, {search['restarts']} restarts"


def _turn_text(turn: dict[str, Any], unit: str) -> str:
    """The turn envelope's bracket of a serial arm's fixed bodies (`analyses.collision_volume`)."""
    if "lower" not in turn:
        return (f"the turn envelope's bracket, estimated on the pre-scan's grid (half-width "
                f"{fmt(turn['estimated_half_width'], 2)} {unit}), is wider than the tolerance: measured in 3-D")
    bodies = ", ".join(e["link"] for e in turn["enveloped"])
    bracket = (f"{bodies} bracketed: {fmt(turn['lower'], 6)} +/- {fmt(turn['lower_error_estimate'], 2)} (swept over "
               f"a full turn) to {fmt(turn['upper'], 6)} +/- {fmt(turn['upper_error_estimate'], 2)} {unit} (their "
               f"pairs left out), half-width {fmt(turn['half_width'], 2)}")
    return bracket if turn["route"] == "envelope" else f"{bracket}: too wide, measured in 3-D"


_LENGTHS = {"b", "d", "L", "rod_spacing", "stroke", "l1", "l2"}
_ANGLES = {"beta", "alpha", "theta_limits", "phi_limits", "theta_zero", "lower", "upper"}


def _parameter_rows(parameters: dict[str, Any], prismatic: frozenset[int] = frozenset()) -> list[tuple[str, str]]:
    """(name [unit], value) rows: lengths in m, angles shown in degrees; `prismatic`: the
    entries of a joint list (a serial arm's lower, upper) that are lengths, kept in m."""
    rows = []
    for k, v in parameters.items():
        if k in _ANGLES:
            if isinstance(v, (list, tuple)):
                shown: Any = [x if i in prismatic else math.degrees(x) for i, x in enumerate(v)]
                unit = "m" if len(prismatic) == len(v) else "deg; m for prismatic" if prismatic else "deg"
            else:
                shown, unit = math.degrees(v), "deg"
            rows.append((f"{k} [{unit}]", fmt(shown, 6)))
        else:
            rows.append((f"{k} [m]" if k in _LENGTHS else k, fmt(v, 6)))
    return rows


def _not_converged(ws: Any) -> str:
    """Why a measurement did not converge, naming the targets whose own estimate failed."""
    failed = ws.unconverged()
    if not failed:
        if not ws.total > 0:  # a coarser grid can only see less
            return ("nothing was found inside: the workspace is empty within the limits, or thinner than --step "
                    "can see; try a smaller --step or check the limits")
        return "the volume did not converge (the evaluation budget ran out); try a larger --step or --rtol"
    by_reason: dict[str, list[str]] = {}
    for name, why in failed.items():
        by_reason.setdefault(why, []).append(name)
    detail = "; ".join(f"{', '.join(names)}: {why}" for why, names in by_reason.items())
    if ws.targets[-1] not in failed:
        advice = "the union converged; try a smaller --step, or leave those branches out with --modes"
    elif ws.fixed_error_binds()[-1]:
        advice = "a smaller --step cannot help; the estimate and its error are the answer at this --rtol"
    elif "search budget" in failed[ws.targets[-1]]:
        advice = "a smaller --step costs more searches; a larger --step or --rtol (e.g. 1e-2) needs fewer"
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
    robot = getattr(mech, "robot", None)  # a serial arm's joints, some of which may be prismatic
    kinds = {d.name: d.kind for d in robot.dofs} if robot is not None else {}
    prismatic = frozenset(i for i, n in enumerate(ws.parameters.get("joints", ())) if kinds.get(n) == "prismatic")
    lines.append(key_values(_parameter_rows({k: v for k, v in ws.parameters.items() if k != "orientation"}, prismatic),
                            digits=None))
    lines += ["", table([mech.branch_kind, f"{key} [{unit}]", f"error estimate [{unit}]"], rows),
              mech.branch_legend, ""]
    lo, hi = payload["bbox"]
    # nothing inside: no relative error and no box (JSON: bbox null), rather than "inf" and "nan"
    rel = f"{fmt(ws.error / ws.total, 2)} relative; " if ws.total > 0 else ""
    box = (f"{[round(x, 4) for x in lo]} .. {[round(x, 4) for x in hi]}"
           if all(x is not None and math.isfinite(x) for x in [*lo, *hi]) else "none (no sample inside)")
    lines.append(key_values([
        (f"{key} [{unit}]", (f"{fmt(ws.total, 8)} +/- {fmt(ws.error, 2)} (estimated error, {rel}"
                            f"rtol {fmt(r.rtol, 2)}; {'converged' if r.converged else 'NOT converged'})")),
        ("method", (f"none needed: {ws.measure_zero}" if ws.measure_zero else
                    "cell refinement" if payload.get("method") != "columns" else
                    f"sampled columns (roots to {fmt(getattr(r, 'root_tol', 0.0), 2)} m) + adaptive Gauss quadrature; "
                    "inside intervals or gaps "
                    f"shorter than the column step {fmt(r.step)} m can be missed" if ws.planar or exact is None else
                    f"exact columns ({exact}) + Gauss rules between located breaks; a feature narrower "
                    f"than the node spacing {fmt(r.step)} m across columns can be missed")),
        *([("not converged", _not_converged(ws))] if not r.converged else []),
        ("bounding box of inside samples [m]", box),
        ("points evaluated", f"{r.points_evaluated:,}"),
        *([("singular points inside", len(payload["singular_points"])),
           ("singular loci", "; ".join(f"{k} " + ", ".join(f"{a.replace('_', ' ')} {b}" for a, b in v.items())
                                       for k, v in payload["singularities"].items()))]
          if payload["singularities"] else
          [("singularities", (f"not scanned for this robot here (`kinematics singularities {ws.robot}` "
                              "bounds its singular joint boxes)") if "reach_search" in mech.capabilities
            else "not done with the end effector held at a rotation" if payload.get("orientation")
            else "not scanned for this robot")]),
        ("time [s]", f"{payload['seconds']:.2f} (volume {payload['volume_seconds']:.2f})"),
    ], digits=None))
    if paper:
        lines += ["", *mech.reference_lines(paper)]
    return "\n".join(lines)
