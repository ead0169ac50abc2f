"""A fixed tool orientation (`kinematics.mechanisms.orientation.ToolOrientation`) in a serial arm's
reach search: a whole rotation (roll, pitch, yaw) or one tool axis (the frame's z axis along a
world direction, free to spin about it).

What the search matches (`vectors`): the frame's z axis for a tool axis, its x and z axes for a
whole rotation (two orthonormal columns fix a rotation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from kinematics.mechanisms.orientation import ToolOrientation
from kinematics.mechanisms.serial.joint_box import Setup
from kinematics.model.robot import Robot


def oriented_setup(robot: Robot, kin: Any, s: Setup, orientation: ToolOrientation, tol: float) -> Setup:
    """The setup with every chain joint searched (a joint that never moves the point still turns
    the tool) but those that only spin the tool about a held axis (`_spins_tool_axis`, within
    0.1 `tol` [m] of the search's residual), and the mode a fixed orientation allows: a solid of revolution only when the
    constraint is unchanged by the base's turn (a tool axis along the base axis)."""
    import dataclasses

    from kinematics.mechanisms.serial.joint_box import dof_of

    dofs = [dof_of(robot, int(v)) for v in kin.idx_v]
    robot.require_ranges([robot.dofs[i].name for i in dofs], "a workspace")
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)[dofs]
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)[dofs]
    kinds = [robot.dofs[i].kind for i in dofs]
    periodic = np.array([k == "continuous" or (k == "revolute" and h - l >= 2 * math.pi - 1e-9)
                         for k, l, h in zip(kinds, lo, hi, strict=True)])
    mode = s.mode
    if mode == "revolved" and not orientation.invariant_about(np.asarray(s.axis_direction)):
        mode = "spatial"
    first = 1 if mode == "revolved" else 0
    keep = np.ones(len(dofs), bool)
    keep[:first] = False
    if orientation.kind == "axis":
        keep &= ~_spins_tool_axis(robot, kin, 0.1 * tol / max(s.reach, 1e-3))
    active = np.array(dofs, dtype=int)[keep]
    return dataclasses.replace(s, mode=mode, active=active, lo=lo[keep], hi=hi[keep], periodic=periodic[keep],
                               fixed=tuple(robot.dofs[d].name for d, k in zip(dofs, keep, strict=True)
                                           if not k and d not in dofs[:first]))


def reduced(robot: Robot, kin: Any, orientation: ToolOrientation, tol: float, reach: float) -> ToolOrientation:
    """A whole rotation is its tool z axis alone when a full-turn joint only spins the tool about
    that axis (`_spins_tool_axis`; the UR5's wrist 3): any spin about z is then reachable without
    moving the point or the axis, so the two sets are equal (exact). Otherwise `orientation`."""
    if orientation.kind != "rotation":
        return orientation
    from kinematics.mechanisms.serial.joint_box import dof_of

    spins = _spins_tool_axis(robot, kin, 0.1 * tol / max(reach, 1e-3))
    dofs = [robot.dofs[dof_of(robot, int(v))] for v in kin.idx_v]
    full = np.array([d.kind == "continuous" or (d.kind == "revolute" and d.upper - d.lower >= 2 * math.pi - 1e-9)
                     for d in dofs])
    if not (spins & full).any():
        return orientation
    return ToolOrientation("axis", orientation.matrix, f"{orientation.text} (as its z axis: a full-turn joint spins the "
                                                       "tool about it)")


def _spins_tool_axis(robot: Robot, kin: Any, angle: float) -> np.ndarray:
    """(n,) per chain joint: it only spins the tool about the tool's z axis: it never moves the
    point and its axis is within `angle` [rad] of the tool's z axis at 64 probe configurations (the
    UR5's wrist 3: 5e-12 rad, its URDF's rounded pi / 2), so neither the point nor a held z axis
    depends on it beyond the search's tolerance: it drops out of a tool axis's search, held at a
    value in its range."""
    from kinematics.generic.batched import configurations

    rng = np.random.default_rng(0)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    poses, J = kin.fk_jacobian(configurations(robot, rng.uniform(lo, hi, (64, robot.nv))))
    cols = [int(v) for v in kin.idx_v]
    lin, ang = J[:, :3, cols], J[:, 3:, cols]  # (64, 3, n)
    z = poses.rotation[:, :, 2]  # the tool's z axis in the world (64, 3)
    along = np.linalg.norm(np.cross(np.moveaxis(ang, 1, 2), z[:, None, :]), axis=2)  # (64, n)
    return np.asarray((np.abs(lin).max(axis=(0, 1)) <= 1e-12) & (along.max(axis=0) <= angle)
                      & (np.linalg.norm(ang, axis=1).min(axis=0) > 0.5))
