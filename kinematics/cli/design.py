"""`kinematics usable-workspace`, `dexterity`, `synthesize` and `workspace-mesh`: their arguments and handlers."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from kinematics.cli.args import (
    Command,
    collision_args,
    collision_checks,
    integer,
    load,
    mode_of,
    orientation_args,
    orientation_of,
    positive,
    robot_arg,
)
from kinematics.cli.report import Out, compile_notice, emit, fmt, key_values
from kinematics.files import check_output, write_atomic

if TYPE_CHECKING:
    from kinematics.model.robot import Robot


def register(command: Command) -> None:
    p = command("usable-workspace", cmd_usable_workspace, "the largest axis-aligned cube, vertical cylinder or "
                "sphere (a planar robot: square or disk) where every point is reachable, non-singular and has "
                "kappa <= K (any mechanism with ik and Jacobians: p2us, delta, scara, a closed loop)")
    robot_arg(p)
    p.add_argument("--shape", required=True, choices=["cube", "cylinder", "sphere", "square", "disk"],
                   help="the shape: cube, cylinder, sphere in a spatial task space; square, disk in a planar one")
    p.add_argument("--kappa-max", type=positive, default=10.0, metavar="K",
                   help="largest condition number sigma_max/sigma_min of the forward Jacobian J (default 10)")
    p.add_argument("--mode", help="working mode such as --- (default), or union")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuators' only")
    p.add_argument("--step", type=positive, default=0.02, metavar="M", help="coarse grid step [m] (default 0.02)")
    collision_args(p)

    p = command("dexterity", cmd_dexterity, "global conditioning index (mean 1/kappa), mean Yoshikawa index and "
                "mean smallest radius with 95 %% error bars (randomised quasi-Monte Carlo), per mode and for their "
                "union (serial arms: the best configuration their search finds); per-cell tables; conditioning maps")
    robot_arg(p)
    p.add_argument("--mode", help="one working mode / elbow such as --- or up (default: every one, and the union)")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuators' only")
    p.add_argument("--samples", type=integer, default=16384, metavar="N",
                   help="points per replicate, rounded up to a power of two (default 16384)")
    p.add_argument("--replicates", type=integer, default=8, metavar="R",
                   help="independently scrambled Sobol' sets, >= 2 (default 8)")
    p.add_argument("--seed", type=integer, default=0, metavar="S", help="random seed of the scrambling (default 0)")
    p.add_argument("--step", type=positive, metavar="M",
                   help="grid step of the maps (--plot, --export) [m] (default: the bounding box's longest side / 50)")
    p.add_argument("--plot", metavar="FILE.png", help="write a conditioning map (slices of 1/kappa)")
    p.add_argument("--export", metavar="FILE.html", help="write a Meshcat scene: points coloured by 1/kappa")
    p.add_argument("--cells", type=integer, metavar="N",
                   help="also a per-cell table of the union: a grid of N cells along the bounding box's longest "
                        "side, each cell's measure, mean 1/kappa, Yoshikawa index and smallest radius with error bars "
                        "(--json key cells: step_m, origin, shape, rows)")
    p.add_argument("--cells-out", metavar="FILE.csv", help="write the per-cell table as CSV (needs --cells)")
    orientation_args(p, "the dexterity over the tool positions reachable (J restricted to the joint velocities "
                        "that keep the orientation)")

    p = command("synthesize", cmd_synthesize, "p2us, delta: multi-objective dimensional synthesis (NSGA-II) on "
                "Dask: maximise the usable cube and the GCI, minimise the footprint; the Pareto front")
    robot_arg(p)
    p.add_argument("--param", action="append", metavar="NAME=LOWER:UPPER",
                   help="a design variable and its bounds (repeatable) [m, rad]: p2us b, d, L, beta, theta_zero, "
                        "rod_spacing, stroke_min, stroke_max; delta R, r, la, lb, cone, theta_min, theta_max, "
                        "elbow_socket, platform_socket")
    p.add_argument("--population", type=integer, default=16, metavar="N", help="designs per generation (default 16)")
    p.add_argument("--generations", type=integer, default=8, metavar="G", help="generations (default 8)")
    p.add_argument("--seed", type=integer, default=0, metavar="S", help="random seed (default 0): same seed, same front")
    p.add_argument("--mode", help="working mode of the cube and the GCI: --- (default) or union")
    p.add_argument("--kappa-max", type=positive, default=10.0, metavar="K",
                   help="largest condition number in the usable cube (default 10)")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuators' only")
    p.add_argument("--cube-cells", type=integer, default=40, metavar="N",
                   help="coarse grid of the cube search: steps along the design's bounding box (default 40)")
    p.add_argument("--gci-samples", type=integer, default=4096, metavar="N",
                   help="GCI points per replicate (4 replicates; default 4096)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="a running dask scheduler (default: an embedded "
                                                            "local cluster)")
    p.add_argument("--workers", type=integer, metavar="N",
                   help="worker processes of the local cluster, 1 to 4 per core (default: cores)")
    p.add_argument("--out", metavar="FILE.csv", help="write the Pareto front as CSV")
    p.add_argument("--plot", metavar="FILE.png", help="write the Pareto front's figure")
    collision_args(p, "; the usable cube is then collision-free (each design's URDF generated with the robot's "
                      "collision sizes; the GCI stays kinematic)")

    p = command("workspace-mesh", cmd_workspace_mesh, "p2us, delta (any spatial mechanism with a workspace margin): a "
                "working mode's workspace boundary as a watertight triangle mesh (STL, PLY or glTF binary)")
    robot_arg(p)
    p.add_argument("--mode", help="working mode such as --- (default), or union")
    p.add_argument("-o", required=True, metavar="FILE.stl|.ply|.glb", help="the mesh file")
    p.add_argument("--step", type=positive, default=0.01, metavar="M", help="grid step [m] (default 0.01)")
    p.add_argument("--limits", default="all", choices=["all", "actuators"],
                   help="all limits (default), or the actuator strokes only")


def cmd_usable_workspace(args: argparse.Namespace) -> int:
    """Largest cube, cylinder or sphere in the well-conditioned workspace."""
    return usable_workspace(args, load(args), emit)


def cmd_dexterity(args: argparse.Namespace) -> int:
    """Global conditioning index and mean Yoshikawa index with error bars; conditioning maps."""
    return dexterity(args, load(args), emit)


def cmd_synthesize(args: argparse.Namespace) -> int:
    """Multi-objective dimensional synthesis (NSGA-II) on Dask."""
    return synthesize(args, load(args), emit)


def cmd_workspace_mesh(args: argparse.Namespace) -> int:
    """A working mode's workspace boundary as a watertight mesh."""
    return workspace_mesh(args, load(args), emit)


def usable_workspace(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses.usable import default_branch, usable
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    compile_notice(args, mech.kernels())  # before the branches: a generic closed loop's come from its solver
    mode = mode_of(args, default_branch(mech))
    checks = collision_checks(args, robot)
    margin_of = None
    if checks is not None:
        from kinematics.analyses.collisions import margin_builder

        margin_of = margin_builder(mech, robot, checks, args.limits)
    res = usable(mech, args.shape, branch=mode, kappa_max=args.kappa_max, limits=args.limits, step=args.step,
                 margin_of=margin_of)
    size_keys = {"cube": ("edge_m",), "cylinder": ("radius_m", "height_m"), "sphere": ("radius_m",),
                 "square": ("edge_m",), "disk": ("radius_m",)}[res.shape]
    # a square's or a disk's measure is an area: its own keys, not a volume's in other units
    measure, unit = ("area", "m2") if res.planar else ("volume", "m3")
    payload = {
        "robot": robot.name,
        "mode": mode,
        "shape": res.shape,
        "center_m": res.center.tolist(),
        "size_m": dict(zip(size_keys, res.size, strict=True)),
        f"{measure}_{unit}": res.volume,
        "kappa_max": args.kappa_max,
        "limits": args.limits,
        "step_m": args.step,
        "check": {"samples": res.samples, "spacing_m": res.spacing, "min_field": res.min_field,
                  "inside": res.min_field >= 0, "larger_1pct_fails": res.larger_fails,
                  f"{measure}_bound_{unit}": res.volume_bound, "optimality_gap": res.optimality_gap},
    }
    if res.planar:
        payload["task_axes"] = list(mech.task_axes)
    if checks is not None:
        from kinematics.analyses.collisions import summary

        payload["collisions"] = summary(checks)

    def human() -> str:
        return key_values([
            ("robot", f"{robot.name}, mode {mode}, kappa <= {fmt(args.kappa_max)}, no singularity"
                      + ("" if checks is None else f", no collision ({len(checks.pairs)} pairs)")),
            ("shape", res.shape),
            ("centre", f"{[round(c, 6) for c in res.center.tolist()]} m"
                       + (f" ({', '.join(mech.task_axes)})" if res.planar else "")),
            *((k.removesuffix("_m"), f"{fmt(v)} m") for k, v in payload["size_m"].items()),
            (measure, f"{fmt(res.volume)} m^{unit[-1]}"),
            ("inside check", (f"{res.samples} samples at {fmt(res.spacing)} m ({'outline' if res.planar else 'surface'} "
                              f"at half): {'pass' if res.min_field >= 0 else 'FAIL'}")),
            ("1 % larger", f"fails at the centre and {3 ** len(res.center) - 1} neighbours" if res.larger_fails
             else "fits somewhere nearby"),
            ("optimum", (f"at most {fmt(res.volume_bound)} m^{unit[-1]} ({100 * res.optimality_gap:.1f} % more "
                         f"{measure}), over the region as sampled on the finest grid")),
        ])

    out(args, payload, human)
    return 0


def workspace_mesh(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses.boundary_mesh import export
    from kinematics.analyses.boundary_mesh import workspace_mesh as mesh_of

    check_output(args.o, "-o", "mesh")
    from kinematics.analyses.usable import default_branch
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    compile_notice(args, mech.kernels())  # before the branches: a generic closed loop's come from its solver
    mode = mode_of(args, default_branch(mech))
    mesh = mesh_of(mech, mode, args.step, args.limits)
    write_atomic(args.o, lambda tmp: export(mesh, tmp), "-o")
    payload = {"robot": robot.name, "mode": mode, "file": args.o, "faces": len(mesh.mesh.faces),
               "watertight": mesh.watertight, "volume_m3": mesh.volume, "step_m": args.step,
               "volume_bound_m3": mesh.tolerance, "boundary_cells": mesh.boundary_cells}

    def human() -> str:
        return key_values([
            ("robot", f"{robot.name}, mode {mode}"), ("file", args.o), ("faces", mesh.mesh.faces.shape[0]),
            ("watertight", mesh.watertight), ("volume", f"{fmt(mesh.volume)} m^3"),
            ("bound", (f"|volume - true| <= {fmt(mesh.tolerance)} m^3 ({mesh.boundary_cells} boundary cells "
                      f"x step^3)")),
            ("step", f"{fmt(args.step)} m"),
        ])

    out(args, payload, human)
    return 0


def dexterity(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses.dexterity import dexterity as measure
    from kinematics.mechanisms import UNION, mechanism_of
    from kinematics.mechanisms.base import Mechanism

    orientation = orientation_of(args)
    mech: Mechanism = mechanism_of(robot, orientation)
    compile_notice(args, mech.kernels())
    if args.mode is not None:
        mech.check_target(args.mode)  # the refusal lists union too
    branches = None if args.mode in (None, UNION) else [args.mode]
    if args.cells_out and args.cells is None:
        from kinematics.errors import InvalidInputError

        raise InvalidInputError("--cells-out", "needs --cells N (the grid of the table)")
    if args.cells_out:
        check_output(args.cells_out, "--cells-out", "csv")
    res = measure(mech, branches, limits=args.limits, samples=args.samples, replicates=args.replicates,
                  seed=args.seed, cells=args.cells)
    payload = res.as_dict()
    if orientation is not None:
        payload["orientation"] = orientation.as_dict()
    target = payload["target"]
    # the map and the scene (which refuse a --step too fine) are built before any file is written,
    # so a command that fails leaves none of its outputs behind
    fig = scene = None
    if args.plot:
        from kinematics.views import plots

        plots.headless()
        fig = plots.conditioning_map(mech, target, args.limits, args.step)
    if args.export:
        from kinematics.views.meshcat import conditioning_view

        scene = conditioning_view(mech, target, limits=args.limits, step=args.step)
    if args.cells_out:
        write_atomic(args.cells_out, _cells_csv(payload["cells"]["rows"]), "--cells-out")
    if fig is not None:
        plots.save(fig, args.plot)
    if scene is not None:
        scene.export(args.export)

    def human() -> str:
        from kinematics.cli.report import table

        unit = payload["yoshikawa_unit"]
        key = "area_m2" if res.planar else "volume_m3"

        def pm(v: float | None, e: float | None) -> str:
            if v is None:
                return "empty"
            return f"{fmt(v, 4)} +/- {fmt(e, 2)}" if e is not None else f"{fmt(v, 4)} (error unbounded)"

        def row(t: str, e: dict) -> tuple[str, ...]:
            return (t, pm(e["gci"], e["gci_error"]), pm(e["yoshikawa_mean"], e["yoshikawa_error"]),
                    pm(e["smallest_radius_mean"], e["smallest_radius_error"]), pm(e[key], e[f"{key}_error"]))

        rows = [row(t, e) for t, e in payload["modes"].items()]
        if len(rows) != 1:
            rows.append(row(UNION, payload))
        notes = []
        if any(res.yoshikawa_diverges) or any(res.yoshikawa_heavy_tail):
            notes.append("Yoshikawa error unbounded: a type II singularity crosses or bounds the region (the "
                         "forward J grows like 1/distance there), so its mean is dominated by a few samples")
        if res.mixed_units:
            notes.append("J mixes m and rad columns: kappa taken with 1 rad <-> 1 m")
        return "\n".join([
            (f"{robot.name}: dexterity ({args.limits} limits), {res.replicates} scrambled Sobol' sets of "
             f"{res.samples} points, seed {res.seed}, {res.seconds:.2f} s; errors are 95 % half-widths"),
            "",
            table([mech.branch_kind, "GCI (mean 1/kappa)", f"mean Yoshikawa [{unit}]", f"mean smallest radius [{payload['smallest_radius_unit']}]",
                   "area [m^2]" if res.planar else "volume [m^3]"], rows),
            *(["", *notes] if notes else []),
            f"{UNION}: {payload['configurations']}",
            *([f"tool held at {orientation.text}: J restricted to the joint velocities that keep it"]
              if orientation is not None else []),
            *([(f"per-cell table: {len(payload['cells']['rows'])} cells of {fmt(payload['cells']['step_m'], 4)} m "
               f"(--json key cells{'; written to ' + args.cells_out if args.cells_out else ''})")]
              if "cells" in payload else []),
        ])

    out(args, payload, human)
    return 0


def _cells_csv(rows: list[dict]) -> str:
    """The per-cell table as CSV: one line per cell, vectors split per axis, empty for None."""
    if not rows:
        return ""
    d = len(rows[0]["index"])
    head = [f"{k}_{a}" for k in ("index", "lower", "upper") for a in range(d)]
    rest = [k for k in rows[0] if k not in ("index", "lower", "upper")]
    lines = [",".join(head + rest)]
    for r in rows:
        vals = [*r["index"], *r["lower"], *r["upper"], *(r[k] for k in rest)]
        lines.append(",".join("" if v is None else repr(v) for v in vals))
    return "\n".join(lines) + "\n"


def synthesize(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses import synthesis as syn
    from kinematics.cli.report import show_progress, table
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    family = syn.family_of(mech)
    bounds = [syn.Bound.parse(p, family) for p in args.param or []]
    collisions = None
    if args.collisions or args.obstacles:
        from kinematics.analyses.collisions import design_options

        collisions = design_options(robot, args.collisions, args.obstacles)
    settings = syn.Settings(branch=mode_of(args, "---"), kappa_max=args.kappa_max, limits=args.limits,
                            cube_cells=args.cube_cells, gci_samples=args.gci_samples, seed=args.seed,
                            collisions=collisions)
    res = syn.synthesize(mech, bounds, population=args.population, generations=args.generations, seed=args.seed,
                         settings=settings, scheduler=args.scheduler, workers=args.workers,
                         progress=show_progress(args))
    if args.out:
        write_atomic(args.out, res.to_csv(), "--out")
    if args.plot:
        from kinematics.views import plots

        plots.headless()
        plots.save(plots.pareto_front(res, {**res.reference, "label": f"{robot.name} as built"}), args.plot)
    payload = {"robot": robot.name, **res.as_dict(), "scheduler": args.scheduler or "local"}

    ref = res.reference
    gap = ref.get("gap")

    def human() -> str:
        cols = list(res.columns)
        return "\n".join([
            (f"{robot.name}: NSGA-II, {res.generations} generations x {res.population} designs "
             f"({len(res.history)} evaluated on {payload['scheduler']}) in {res.seconds:.1f} s, seed {res.seed}"),
            (f"objectives: usable cube edge (mode {res.branch}, kappa <= {fmt(res.kappa_max)}; a checked lower "
             f"bound) max, GCI max, footprint ({res.footprint_text}) min"),
            f"Pareto front: {len(res.rows)} designs" + (f"; written to {args.out}" if args.out else ""),
            "",
            table(cols, [[r[c] for c in cols] for r in res.rows], digits=4),
            "",
            (f"{robot.name} as built: edge {fmt(ref['cube_edge_m'], 4)} m, GCI {fmt(ref['gci'], 4)}, footprint "
             f"{fmt(ref['footprint_m'], 4)} m; " + (
                 f"{'dominated by' if gap['dominated'] else 'not dominated by'} the front, epsilon "
                 f"{gap['epsilon']:+.3f} of the objectives' ranges" if gap else "no feasible front")),
        ])

    out(args, payload, human)
    return 0
