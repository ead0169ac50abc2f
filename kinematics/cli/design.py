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
    from kinematics.analyses.usable import p2us_usable

    params = _params(robot)
    mode = args.mode or "---"
    res = p2us_usable(params, args.shape, mode=mode, kappa_max=args.kappa_max, step=args.step)
    size_keys = {"cube": ("edge_m",), "cylinder": ("radius_m", "height_m"), "sphere": ("radius_m",)}[res.shape]
    payload = {
        "robot": robot.name,
        "mode": mode,
        "shape": res.shape,
        "center_m": res.center.tolist(),
        "size_m": dict(zip(size_keys, res.size, strict=True)),
        "volume_m3": res.volume,
        "kappa_max": args.kappa_max,
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
