"""`kinematics info`: joints, limits, frames and parameters of a robot, and the two-parser check."""

from __future__ import annotations

import argparse
from typing import Any

from kinematics.cli.args import EXIT_OK, Command, load, robot_arg
from kinematics.cli.report import emit


def register(command: Command) -> None:
    p = command("info", cmd_info, "joints, limits, frames and parameters of a robot")
    robot_arg(p)


def cmd_info(args: argparse.Namespace) -> int:
    """Joints, limits, frames, parameters and the two-parser check."""
    import numpy as np

    from kinematics.cli.report import key_values, table
    from kinematics.mechanisms import mechanism_of, plane_of
    from kinematics.model.robot import parser_agreement

    robot = load(args)
    agree = parser_agreement(robot)
    mech = mechanism_of(robot)
    params = mech.design_parameters()
    sources = mech.parameter_sources(str(robot.urdf_path)) if params else {}
    found = plane_of(robot)
    axes = None if found is None else found.axes
    mob = _loop_mobility(robot) if robot.loops is not None else None
    mobility = robot.nv if mob is None else mob["mobility"]
    payload = {
        "name": robot.name,
        "urdf": str(robot.urdf_path),
        "dof": robot.nv,
        "joint_coordinates": robot.nv,
        "mobility": mobility,
        "grubler_mobility": None if mob is None else mob["grubler"],
        "mobility_pose": None if mob is None else mob["pose"],
        "mobility_note": None if mob is None else mob["note"],
        "joints": [{"name": d.name, "type": d.kind, "lower": d.lower, "upper": d.upper, "range_given": d.range_given}
                   for d in robot.dofs],
        "tool_frame": robot.tool_frame,
        "frames": list(robot.frame_names),
        "planar": axes is not None,
        "plane_axes": None if axes is None else ["xyz"[i] for i in axes],
        "plane": None if found is None else found.as_dict(),
        "parameters": params,
        "parameter_sources": sources,
        "parsers_agree": {
            "frames": agree.frames,
            "max_position_error": agree.max_position_error,
            "max_rotation_error": agree.max_rotation_error,
        },
        "loops": _loops_payload(robot),
    }

    def human() -> str:
        unit = {"prismatic": "m", "revolute": "rad", "continuous": "rad"}
        if mob is None:
            head = f"{robot.nv} degrees of freedom"
        elif mobility is None:
            head = f"{robot.nv} joint coordinates, Grübler-Kutzbach count {mob['grubler']} (numeric mobility unknown)"
        else:
            head = f"{robot.nv} joint coordinates, mobility {mobility}"
        parts = [
            f"{robot.name}  ({robot.urdf_path})",
            head + f", tool frame {robot.tool_frame!r}, " + (_plane_text(found) if found else "spatial"),
            "",
            table(
                ["joint", "type", "lower", "upper", "unit"],
                [(d.name, d.kind, *(v if np.isfinite(v) or d.kind == "continuous" else "none given"
                                     for v in (d.lower, d.upper)), unit[d.kind]) for d in robot.dofs],
            ),
        ]
        if mob is not None:
            parts += ["", (f"mobility {mobility} = nv - rank of the loop-constraint Jacobian at {mob['pose']}; "
                           f"Grübler-Kutzbach count {mob['grubler']}" if mobility is not None
                           else f"mobility: {mob['note']}")]
        if robot.unranged:
            parts += ["", (f"{len(robot.unranged)} joint(s) without a range in the URDF (<limit> without lower/upper): "
                           "unbounded; a command that needs the range of one asks for it (--range JOINT=LO:HI)")]
        if params and sources:
            parts += ["", "parameters (read from the URDF and its sidecar; source of each number):",
                      table(["parameter", "value", "source"], [(k, v, sources.get(k, "")) for k, v in params.items()])]
        elif params:
            parts += ["", "parameters (read from the URDF):", key_values(params.items(), None)]
        if payload["loops"]:
            lp = payload["loops"]
            kinds = [c["type"] for c in lp["constraints"]]
            counts = ", ".join(f"{kinds.count(k)} {k}" for k in dict.fromkeys(kinds))
            parts += ["", f"loop closures ({lp['sidecar']}): {counts or 'none'}; actuated: {', '.join(lp['actuated'])}"]
        parts += [
            "",
            f"frames ({len(robot.frame_names)}): {', '.join(robot.frame_names)}",
            "",
            (f"Pinocchio vs yourdfpy: {agree.frames} link frames, max position error "
             f"{agree.max_position_error:.2e} m, max rotation error {agree.max_rotation_error:.2e} rad"),
        ]
        return "\n".join(parts)

    emit(args, payload, human)
    return EXIT_OK


def _plane_text(found: Any) -> str:
    i, j = ("xyz"[a] for a in found.axes)
    where = "its closed motion" if found.closed else "its joint axes"
    return f"planar in {i}-{j} at {'xyz'[found.normal]} = {found.offset:.6g} m (decided on {where})"


def _loop_mobility(robot: Any) -> dict[str, Any]:
    """A closed-loop robot's mobility for `info`: the numeric one (nv - rank of the loop-constraint
    Jacobian) at the default closed pose, beside the Grübler-Kutzbach count; the count alone, with
    a note, when no closed pose is found."""
    from kinematics.analyses.mobility import grubler, numeric_mobility
    from kinematics.errors import ConvergenceError
    from kinematics.generic.closedloop import ClosedLoop

    count = grubler(robot).mobility
    try:
        a = ClosedLoop(robot).assembly
    except ConvergenceError as exc:
        return {"mobility": None, "grubler": count, "pose": None,
                "note": (f"no closed pose found ({exc}), so no numeric mobility; the Grübler-Kutzbach count "
                         f"{count} alone assumes independent loop constraints (an over-constrained model's "
                         "are not, and the count can then be wrong, even negative)")}
    return {"mobility": numeric_mobility(robot, a.q).mobility, "grubler": count, "pose": a.description, "note": None}


def _loops_payload(robot: Any) -> dict[str, Any] | None:
    if robot.loops is None:
        return None
    return robot.loops.as_dict()
