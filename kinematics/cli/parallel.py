"""CLI handlers for closed-loop robots: the closed forms of a mechanism that answers single-pose
reports (`Mechanism.pose_ik`, `pose_fk`, `pose_jacobians`: the 3-[P2(US)], the Delta), and the
generic Pinocchio closed-loop solver for any other URDF + loop sidecar. Called from the command
modules (`fk`, `ik`, `jacobian`, `mobility`, `views`)."""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np

from kinematics.cli.args import orientation_of
from kinematics.cli.report import Out, compile_notice, key_values, matrix, table
from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.mechanisms import SINGULAR_TOL, SINGULARITY_TYPES, Mechanism, classify, mechanism_of
from kinematics.model.robot import Robot

EXIT_OK, EXIT_NO = 0, 1

POSE_REPORTS = frozenset({"pose_ik", "pose_fk", "pose_jacobians"})
"""The `Mechanism` capabilities behind the closed-form answers of ik, fk and jacobian."""


def closed_forms(robot: Robot) -> Mechanism | None:
    """The robot's mechanism when it answers single-pose reports in closed form (`POSE_REPORTS`),
    else None (then the generic closed-loop solver answers)."""
    mech = mechanism_of(robot)
    return mech if mech.capabilities >= POSE_REPORTS else None


def require_closed_forms(robot: Robot) -> Mechanism:
    mech = closed_forms(robot)
    if mech is None:
        from kinematics.mechanisms import families

        raise UnsupportedRobotError(robot.name, "closed-form IK needs a mechanism with closed forms ("
                                    + ", ".join(families()) + "); its sidecar declares mechanism "
                                    f"{robot.loops.mechanism if robot.loops else None!r}")
    return mech


def position_arg(args: argparse.Namespace, axes: tuple[str, ...] = ("x", "y", "z")) -> np.ndarray:
    """--position as a finite vector of one value per task axis [m]."""
    if args.position is None or len(args.position) != len(axes):
        got = 0 if args.position is None else len(args.position)
        names = " ".join(a.upper() for a in axes)
        raise InvalidInputError("--position", f"give {names} of the end effector [m], got {got} value(s)")
    p = np.array(args.position, dtype=float)
    if not np.all(np.isfinite(p)):
        raise InvalidInputError("--position", f"must be finite, got {p.tolist()}")
    return p


def _solutions_report(title: str, key: str, columns: list[str], digits: int,
                      solutions: list[dict[str, Any]], reason: str | None, label: str = "mode") -> str:
    """Title line, a table of the solutions (their `label`, the values under `key`, within
    limits), their limit violations, and the reason when there is one."""
    parts = [title]
    if solutions:
        parts.append(table([label, *columns, "within limits"],
                           [(s[label], *s[key], s["within_limits"]) for s in solutions], digits))
        lines = [f"  {s[label]}: " + "; ".join(s["violations"]) for s in solutions if s["violations"]]
        parts += (["limit violations:"] + lines) if lines else []
    if reason:
        parts.append(f"reason: {reason}")
    return "\n".join(parts)


def ik(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    """`kinematics ik ROBOT --position ...`: every branch (the SCARA's elbows, the 3-[P2(US)]'s and
    the Delta's working modes) from the mechanism's closed forms (`Mechanism.pose_ik`), with the
    limits each breaks and why none reaches; with --orientation a closed loop's end effector held
    at that rotation."""
    mech = mechanism_of(robot, orientation_of(args))
    if "pose_ik" not in mech.capabilities:
        if mech.closed_loop and {"ik", "joint_values"} <= mech.capabilities:  # the batched solver's
            return _generic_ik(args, robot, mech, out)
        raise UnsupportedRobotError(robot.name, "inverse kinematics is available for planar 2R arms (scara), 3-[P2(US)] "
                                                "(p2us) and Delta robots (delta) in closed form, and for closed loops "
                                                f"by the batched solver; this one is neither ({mech.description})")
    p = position_arg(args, mech.task_axes)
    res = mech.pose_ik(p)
    label = "elbow" if mech.branch_kind == "elbow" else "mode"
    solutions = [{"q": res.q[m], label: name, "within_limits": not res.violations[m],
                  "violations": list(res.violations[m])}
                 for m, name in enumerate(mech.branches) if res.reachable[m]]
    reachable = any(s["within_limits"] for s in solutions)
    if reachable:
        reason = None
    elif not solutions:
        reason = res.reason
    else:
        reason = f"every {mech.branch_kind} breaks a limit ({len(solutions)} assemble; see violations)"
    payload = {"position": p, "reachable": reachable, "reason": reason, "solutions": solutions, "limbs": res.limbs}

    def human() -> str:
        title = f"position {p.tolist()} m: " + ("reachable" if reachable else "NOT reachable")
        u = mech.actuator_unit
        columns = [f"q{i + 1} [{u}]" for i in range(res.q.shape[-1])]
        return _solutions_report(title, "q", columns, 9, solutions, reason, label)

    out(args, payload, human)
    return EXIT_OK if reachable else EXIT_NO


def _generic_ik(args: argparse.Namespace, robot: Robot, mech: Mechanism, out: Out) -> int:
    """`kinematics ik` of a generic closed loop: every working mode the batched solver finds with
    the end effector at --position (`Mechanism.ik`, the workspace margin's solver: it can miss a
    mode, docs/closed-loops.md), its actuator values and the joint ranges its joint values break
    (a revolute angle a whole number of turns from its range counts as within)."""
    compile_notice(args, mech.kernels())  # the task axes already come from the solver
    p = position_arg(args, mech.task_axes)
    res = mech.ik(p[None])
    solutions = []
    for b, name in enumerate(mech.branches):
        if not res.reachable[0, b]:
            continue
        values = mech.joint_values(p, name)
        violations = [f"{d.name} = {values[d.name]:.6g} {'m' if d.kind == 'prismatic' else 'rad'} outside "
                      f"[{d.lower:.6g}, {d.upper:.6g}]" for d in robot.dofs if _outside(d, values[d.name])]
        within = bool(res.within_limits[0, b])
        if not within and not violations:  # only a spherical joint's other representation is out of range
            violations = ["a spherical joint's angles out of their ranges"]
        solutions.append({"q": res.q[0, b], "mode": name, "within_limits": within,
                          "violations": [] if within else violations})
    reachable = any(s["within_limits"] for s in solutions)
    if reachable:
        reason = None
    elif not solutions:
        reason = (f"the batched solver closes the loops in no working mode with the end effector there "
                  f"({', '.join(mech.branches)}; it starts from the atlas, restarts and a continuation from the reference position)")
    else:
        reason = f"every working mode breaks a joint range ({len(solutions)} assemble; see violations)"
    actuators = list(robot.loops.actuated) if robot.loops else []
    held = getattr(mech, "held", None)
    payload = {"position": p, "reachable": reachable, "reason": reason, "solutions": solutions, "actuators": actuators,
               "orientation": None if held is None else held.as_dict()}

    def human() -> str:
        title = (f"position {p.tolist()} m ({', '.join(mech.task_axes)})"
                 + ("" if held is None else f", end effector held at {held.text}") + ": "
                 + ("reachable" if reachable else "NOT reachable"))
        kinds = {d.name: d.kind for d in robot.dofs}
        columns = [f"{a} [{'m' if kinds[a] == 'prismatic' else 'rad'}]" for a in actuators]
        return _solutions_report(title, "q", columns, 9, solutions, reason)

    out(args, payload, human)
    return EXIT_OK if reachable else EXIT_NO


def _outside(dof: Any, value: float, tol: float = 1e-12) -> bool:
    """Whether `value` [rad or m] is outside the joint's range: a revolute angle when no angle a
    whole number of turns from it is inside."""
    if dof.kind == "continuous" or dof.lower - tol <= value <= dof.upper + tol:
        return False
    if dof.kind == "revolute" and np.isfinite(dof.lower):
        turned = dof.lower + (value - dof.lower) % (2 * np.pi)  # in [lower, lower + 2 pi)
        return not (turned <= dof.upper + tol or turned >= dof.lower + 2 * np.pi - tol)
    return True


def actuated_arg(args: argparse.Namespace, robot: Robot) -> np.ndarray:
    n = len(robot.loops.actuated)  # type: ignore[union-attr]
    if args.q is None or len(args.q) != n:
        got = 0 if args.q is None else len(args.q)
        raise InvalidInputError("--q", f"{robot.name} has {n} actuated joints "
                                f"({', '.join(robot.loops.actuated)}), got {got} value(s)")  # type: ignore[union-attr]
    q = np.array(args.q, dtype=float)
    if not np.all(np.isfinite(q)):
        raise InvalidInputError("--q", f"must be finite, got {q.tolist()}")
    if args.degrees:
        kinds = {d.name: d.kind for d in robot.dofs}
        angular = np.array([kinds[a] != "prismatic" for a in robot.loops.actuated])  # type: ignore[union-attr]
        q[angular] = np.radians(q[angular])
    return q


def fk(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    """`kinematics fk p2us|delta [--q Q1 Q2 Q3]`: both assembly modes (closed form); other loop
    robots through the Pinocchio closed-loop solver. Without --q: the actuator values of the
    default closed pose (`ClosedLoop.assembly`: the sidecar's reference, or a pose found)."""
    mech = closed_forms(robot)
    if mech is None:
        return _generic_fk(args, robot, out)
    if args.frame is not None and robot.frame_id(args.frame) != robot.frame_id():
        raise InvalidInputError("--frame", f"{robot.name}'s fk is its platform position from the closed forms "
                                f"(frame {robot.tool_frame!r}); another frame is not computed")
    if args.q is None:
        from kinematics.generic.closedloop import ClosedLoop
        from kinematics.mechanisms.closed_loop import closed_pose

        pose = closed_pose(ClosedLoop(robot))
        q, where = pose.actuated, f"the actuator values of {pose.description}"
    else:
        q, where = actuated_arg(args, robot), "the given actuator values"
    res = mech.pose_fk(q)
    solutions = [{"position": res.p[k], "mode": mode, "within_limits": not viol, "violations": list(viol)}
                 for k, (mode, viol) in enumerate(zip(mech.assembly_modes, res.violations, strict=False))]
    reason = res.reason
    payload = {"q": q, "configuration": where, "exists": bool(res.exists), "reason": reason, "solutions": solutions}

    def human() -> str:
        return _solutions_report(f"actuators q = {q.tolist()} {mech.actuator_unit} ({where})", "position",
                                 ["x [m]", "y [m]", "z [m]"], 12, solutions, reason)

    out(args, payload, human)
    return EXIT_OK if res.exists else EXIT_NO


def _no_position(args: argparse.Namespace, robot: Robot) -> None:
    """A generic closed loop is posed by its actuators: --position and --mode belong to the closed-form
    families."""
    for flag in ("position", "mode"):
        if getattr(args, flag, None) is not None:
            raise InvalidInputError(f"--{flag}", f"{robot.name} has no closed forms: give its actuator values with "
                                    f"--q ({', '.join(robot.loops.actuated)}), or none for its default closed "  # type: ignore[union-attr]
                                    "pose")


def _generic_pose(args: argparse.Namespace, robot: Robot) -> tuple[Any, Any]:
    """(ClosedLoop, ClosedPose): at --q (actuator values), else the default closed pose."""
    from kinematics.generic.closedloop import ClosedLoop
    from kinematics.mechanisms.closed_loop import closed_pose

    q = None if args.q is None else actuated_arg(args, robot)
    loop = ClosedLoop(robot)
    return loop, closed_pose(loop, q)


def _actuators_table(robot: Robot, values: np.ndarray) -> str:
    kinds = {d.name: d.kind for d in robot.dofs}
    names = robot.loops.actuated  # type: ignore[union-attr]
    return table(["actuator", "value", "unit"],
                 [(n, v, "m" if kinds[n] == "prismatic" else "rad") for n, v in zip(names, values, strict=True)], 12)


def _generic_fk(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    """Any other loop robot: the frame's placement at the closed pose (--q, else the default)."""
    from kinematics.generic.serial import forward_kinematics

    _no_position(args, robot)
    frame = robot.model.frames[robot.frame_id(args.frame)].name  # an unknown frame is said before any solve
    _, pose = _generic_pose(args, robot)
    placement = forward_kinematics(robot, pose.q, frame)
    payload = {"frame": frame, "configuration": pose.description, "q": pose.actuated,
               "actuated": list(robot.loops.actuated), "position": placement.position,  # type: ignore[union-attr]
               "rotation": placement.rotation, "residual": pose.residual,
               "joint_values": dict(zip(robot.joint_names, pose.values.tolist(), strict=True))}

    def human() -> str:
        return "\n".join([f"{robot.name}, frame {frame!r}, at {pose.description}", _actuators_table(robot, pose.actuated),
                          "", key_values([("position [m]", placement.position), ("loop residual [m]", pose.residual)], 12),
                          "rotation:", matrix(placement.rotation)])

    out(args, payload, human)
    return EXIT_OK


def jacobian(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    """`kinematics jacobian p2us|delta --position X Y Z [--mode M]`: J, J_x, J_q and the
    singularity type."""
    mech = closed_forms(robot)
    if mech is None:
        return _generic_jacobian(args, robot, out)
    if args.q is not None:
        raise InvalidInputError("--q", f"{robot.name}'s Jacobian is taken at a platform position: give --position X Y Z")
    # the closed forms give the platform's translational J alone: another frame or task would be
    # answered with it, so they are refused (as fk refuses the frame)
    if args.frame is not None and robot.frame_id(args.frame) != robot.frame_id():
        raise InvalidInputError("--frame", f"{robot.name}'s Jacobian is its platform's from the closed forms "
                                f"(frame {robot.tool_frame!r}); another frame is not computed")
    if args.task not in ("auto", "translation"):
        raise InvalidInputError("--task", f"{robot.name}'s Jacobian is its platform's translation (J = Jq^-1 Jx, "
                                "3 x 3); use auto or translation")
    p = position_arg(args)
    res = mech.pose_ik(p)
    if args.mode is not None:
        m = mech.branches.index(mech.check_branches([args.mode])[0])
    else:  # the first mode within limits, else the first that assembles
        ok = np.flatnonzero(res.within_limits) if res.within_limits.any() else np.flatnonzero(res.reachable)
        m = int(ok[0]) if ok.size else 0
    mode = mech.branches[m]
    if not res.reachable[m]:
        payload = {"position": p, "mode": mode, "reachable": False, "reason": res.reason}
        out(args, payload, lambda: f"platform at {p.tolist()} m is NOT reachable: {payload['reason']}")
        return EXIT_NO
    q = res.q[m]
    jac = mech.pose_jacobians(p, q)
    kind = SINGULARITY_TYPES[int(classify(jac.iota_I, jac.iota_II))]
    J = jac.J if np.all(np.isfinite(jac.J)) else None
    payload = {
        "position": p, "mode": mode, "reachable": True, "within_limits": bool(res.within_limits[m]),
        "q": q, "J": J, "Jx": jac.Jx, "Jq": np.diag(jac.Jq), "det_Jx": float(np.linalg.det(jac.Jx)),
        "det_Jq": float(np.prod(jac.Jq)), "singularity": kind,
        "measures": {"iota_I": float(jac.iota_I), "iota_II": float(jac.iota_II), "tolerance": SINGULAR_TOL},
    }

    def human() -> str:
        return "\n".join([
            f"platform at {p.tolist()} m, mode {mode}, q = {np.round(q, 9).tolist()} {mech.actuator_unit}",
            "J = Jq^-1 Jx (qdot = J pdot):", matrix(jac.J, 9) if J is not None else "  (infinite: type I)",
            "Jx:", matrix(jac.Jx, 9), "Jq (diagonal):", matrix(np.diag(jac.Jq), 9),
            key_values([("det Jx", payload["det_Jx"]), ("det Jq", payload["det_Jq"]),
                        (mech.iota_I_label, jac.iota_I), ("iota_II = |det n|", jac.iota_II),
                        ("singularity", f"{kind} (tolerance {SINGULAR_TOL:g})")], 9),
        ])

    out(args, payload, human)
    return EXIT_OK


def _generic_jacobian(args: argparse.Namespace, robot: Robot, out: Out) -> int:
    """Any other loop robot: the constrained Jacobian (frame twist rows per actuator rate) at the
    closed pose (--q, else the default); a pose where the rows asked for are not held by the
    actuators (type II) is refused, saying which rows move and which frames are held."""
    from kinematics.errors import SingularConfigurationError
    from kinematics.generic.serial import task_rows
    from kinematics.mechanisms.closed_loop import constrained_jacobian
    from kinematics.mechanisms.closed_loop.poses import ROW_NAMES

    _no_position(args, robot)
    frame = robot.model.frames[robot.frame_id(args.frame)].name
    rows = tuple(range(6)) if args.task in ("auto", "full") else task_rows(robot, args.task)
    loop, pose = _generic_pose(args, robot)
    try:
        G = constrained_jacobian(loop, pose.q, frame, rows)
    except SingularConfigurationError as exc:
        raise SingularConfigurationError(f"{robot.name}: {exc.what} at {pose.description}", exc.detail) from None
    names = [ROW_NAMES[r] for r in rows]
    payload = {"frame": frame, "configuration": pose.description, "q": pose.actuated,
               "actuated": list(robot.loops.actuated), "position": _frame_position(robot, pose.q, frame),  # type: ignore[union-attr]
               "rows": names, "jacobian": G, "residual": pose.residual,
               "joint_values": dict(zip(robot.joint_names, pose.values.tolist(), strict=True))}

    def human() -> str:
        return "\n".join([f"{robot.name}, frame {frame!r}, at {pose.description}", _actuators_table(robot, pose.actuated),
                          "", (f"constrained Jacobian: rows {', '.join(names)} of the frame's twist (world axes) "
                               "per actuator rate (columns in the order above):"), matrix(G, 9)])

    out(args, payload, human)
    return EXIT_OK


def _frame_position(robot: Robot, q: np.ndarray, frame: str) -> np.ndarray:
    from kinematics.generic.serial import forward_kinematics

    return forward_kinematics(robot, q, frame).position
