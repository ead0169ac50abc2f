"""CLI handlers of `kinematics usable-workspace` and `workspace-mesh` (called from `cli`)."""

from __future__ import annotations

import argparse
from typing import Any

from kinematics.cli.report import Out, fmt, key_values
from kinematics.files import check_output, write_atomic
from kinematics.model.robot import Robot


def _params(robot: Robot) -> Any:
    from kinematics.errors import UnsupportedRobotError
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    if mech.family != "p2us":
        raise UnsupportedRobotError(robot.name, "usable workspaces and boundary meshes support the 3-[P2(US)]")
    return mech.params


def usable_workspace(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses.usable import default_branch, usable
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    mode = args.mode or default_branch(mech)
    res = usable(mech, args.shape, branch=mode, kappa_max=args.kappa_max, limits=args.limits, step=args.step)
    size_keys = {"cube": ("edge_m",), "cylinder": ("radius_m", "height_m"), "sphere": ("radius_m",)}[res.shape]
    payload = {
        "robot": robot.name,
        "mode": mode,
        "shape": res.shape,
        "center_m": res.center.tolist(),
        "size_m": dict(zip(size_keys, res.size, strict=True)),
        "volume_m3": res.volume,
        "kappa_max": args.kappa_max,
        "limits": args.limits,
        "step_m": args.step,
        "check": {"samples": res.samples, "spacing_m": res.spacing, "min_field": res.min_field,
                  "inside": res.min_field >= 0, "larger_1pct_fails": res.larger_fails},
    }

    def human() -> str:
        return key_values([
            ("robot", f"{robot.name}, mode {mode}, kappa <= {fmt(args.kappa_max)}, no singularity"),
            ("shape", res.shape), ("centre", f"{[round(c, 6) for c in res.center.tolist()]} m"),
            *((k.removesuffix("_m"), f"{fmt(v)} m") for k, v in payload["size_m"].items()),
            ("volume", f"{fmt(res.volume)} m^3"),
            ("inside check", (f"{res.samples} samples at {fmt(res.spacing)} m (surface at half): "
                             f"{'pass' if res.min_field >= 0 else 'FAIL'}")),
            ("1 % larger", "fails at the centre and 26 neighbours (near-maximal)" if res.larger_fails
             else "fits somewhere nearby: not proven near-maximal"),
        ])

    out(args, payload, human)
    return 0


def workspace_mesh(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses.boundary_mesh import export, p2us_mesh

    check_output(args.o, "-o", "mesh")
    params = _params(robot)
    mode = args.mode or "---"
    mesh = p2us_mesh(params, mode, args.step, args.limits)
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

    mech = mechanism_of(robot)
    branches = None if args.mode in (None, UNION) else [args.mode]
    res = measure(mech, branches, limits=args.limits, samples=args.samples, replicates=args.replicates,
                  seed=args.seed)
    payload = res.as_dict()
    target = payload["target"]
    if args.plot:
        from kinematics.views import plots

        plots.headless()
        plots.save(plots.conditioning_map(mech, target, args.limits, args.step), args.plot)
    if args.export:
        from kinematics.views.meshcat import conditioning_view

        conditioning_view(mech, target, limits=args.limits, step=args.step).export(args.export)

    def human() -> str:
        from kinematics.cli.report import table

        unit = payload["yoshikawa_unit"]
        key = "area_m2" if res.planar else "volume_m3"

        def pm(v: float | None, e: float | None) -> str:
            if v is None:
                return "empty"
            return f"{fmt(v, 4)} +/- {fmt(e, 2)}" if e is not None else f"{fmt(v, 4)} (error unbounded)"

        rows = [(t, pm(e["gci"], e["gci_error"]), pm(e["yoshikawa_mean"], e["yoshikawa_error"]),
                 pm(e[key], e[f"{key}_error"])) for t, e in payload["modes"].items()]
        if len(rows) > 1:
            rows.append((UNION, pm(payload["gci"], payload["gci_error"]),
                         pm(payload["yoshikawa_mean"], payload["yoshikawa_error"]),
                         pm(payload[key], payload[f"{key}_error"])))
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
            table([mech.branch_kind, "GCI (mean 1/kappa)", f"mean Yoshikawa [{unit}]",
                   "area [m^2]" if res.planar else "volume [m^3]"], rows),
            *(["", *notes] if notes else []),
            "union: the best branch at each point",
        ])

    out(args, payload, human)
    return 0


def synthesize(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    from kinematics.analyses import synthesis as syn
    from kinematics.cli.report import show_progress, table
    from kinematics.mechanisms import mechanism_of

    mech = mechanism_of(robot)
    family = syn.family_of(mech)
    bounds = [syn.Bound.parse(p, family) for p in args.param or []]
    settings = syn.Settings(branch=args.mode or "---", kappa_max=args.kappa_max, limits=args.limits,
                            cube_cells=args.cube_cells, gci_samples=args.gci_samples, seed=args.seed)
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
