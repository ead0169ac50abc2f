"""The one place that decides what a loaded robot is.

`mechanism_of(robot)`:

1. a loop sidecar whose `mechanism:` names a family with closed forms (`FAMILIES`) -> that
   family's mechanism, its design read back from the URDF (its platform frame the tool frame);
2. any other loop sidecar -> `GenericClosedLoop`;
3. an open chain that is a planar 2R arm with joints about z (`ScaraParams.from_robot` accepts
   it) -> `Scara` (closed forms);
4. any other open chain -> `SerialArm`;

and with a fixed tool `orientation` (the reachable set for that orientation) an open chain's
`SerialArm` that asks for it (`with_fixed_orientation`), whatever the above says, or a
`GenericClosedLoop` that holds it (six actuators; the closed-form families' platforms do not turn).

`plane_of(robot)`: planar or spatial, decided once for every command (`info`, `fk`, `jacobian`,
`show`, `mobility`, `workspace-volume`): the plane the end effector moves in with the loops closed
(`kinematics.generic.motion_plane.motion_plane`), or None.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.mechanisms.base import Mechanism
from kinematics.model.robot import Robot

if TYPE_CHECKING:
    from kinematics.generic.motion_plane import MotionPlane
    from kinematics.mechanisms.orientation import ToolOrientation


def _p2us(robot: Robot) -> Mechanism:
    from kinematics.mechanisms.p2us.mechanism import P2US
    from kinematics.mechanisms.p2us.urdf import read_params

    return P2US(read_params(robot.urdf_path, robot.name), robot.name)


def _delta(robot: Robot) -> Mechanism:
    from kinematics.mechanisms.delta.mechanism import Delta
    from kinematics.mechanisms.delta.urdf import read_params

    return Delta(read_params(robot.urdf_path, robot.name), robot.name)


def families() -> dict[str, Callable[[Robot], Mechanism]]:
    """Closed-form families by the sidecar's `mechanism:` value."""
    from kinematics.mechanisms.delta.closed_form import MECHANISM as DELTA
    from kinematics.mechanisms.p2us.urdf import MECHANISM as P2US

    return {P2US: _p2us, DELTA: _delta}


def mechanism_of(robot: Robot, orientation: ToolOrientation | None = None) -> Mechanism:
    """The robot as a `Mechanism` (see the module docstring); with `orientation`, its reachable set
    for that tool orientation (open chains, and closed loops with six actuators: UnsupportedRobotError
    otherwise, when the mechanism is first used for a closed loop).

    Raises:
        InvalidInputError: `robot` is not a `Robot` (a name: load it with `load_robot` first), or
            `orientation` not a `ToolOrientation`.
    """
    if not isinstance(robot, Robot):
        hint = f"; load it first: mechanism_of(load_robot({robot!r}))" if isinstance(robot, str) else ""
        raise InvalidInputError("robot", f"expected a Robot (from load_robot), got {type(robot).__name__}{hint}")
    if orientation is not None:
        from kinematics.mechanisms.orientation import ToolOrientation

        if not isinstance(orientation, ToolOrientation):
            raise InvalidInputError("orientation", "expected a ToolOrientation (ToolOrientation.parse('rpy R P Y') "
                                                   f"or ToolOrientation.axis(d)), got {orientation!r}")
        if robot.loops is not None:
            if robot.loops.mechanism in families():
                raise UnsupportedRobotError(robot.name, "its platform keeps one orientation (a translational "
                                                        "mechanism): no orientation can be chosen")
            from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop

            return GenericClosedLoop(robot, orientation)
        from kinematics.mechanisms.serial.mechanism import with_fixed_orientation

        return with_fixed_orientation(robot, orientation)
    if robot.loops is not None:
        build = families().get(robot.loops.mechanism or "")
        if build is not None:
            if robot.tool_frame != robot.loops.end_effector:  # load_robot(tool_frame=...)
                raise UnsupportedRobotError(robot.name, (
                    f"its closed forms compute the position of its platform frame {robot.loops.end_effector!r}; "
                    f"the tool frame {robot.tool_frame!r} is not analysed"))
            return build(robot)
        from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop

        return GenericClosedLoop(robot)
    from kinematics.mechanisms.scara.closed_form import ScaraParams
    from kinematics.mechanisms.scara.mechanism import Scara

    try:
        params = ScaraParams.from_robot(robot)
    except UnsupportedRobotError:
        from kinematics.mechanisms.serial.mechanism import SerialArm

        return SerialArm(robot)
    return Scara(params, robot.name)


def plane_of(robot: Robot) -> MotionPlane | None:
    """The plane the end effector moves in (loops closed), or None where its motion is spatial: the
    one decision every command reports (module docstring; cached per robot)."""
    from kinematics.generic.motion_plane import motion_plane

    return motion_plane(robot)
