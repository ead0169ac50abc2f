"""Any open chain as a `Mechanism`: forward kinematics and Jacobians of its tool frame's position
from the compiled batched kinematics (`kinematics.generic.batched`).

Its margin is a reachability search (`kinematics.mechanisms.serial.reach`: bounded
Levenberg-Marquardt from seeded restarts and warm starts, compiled, on every core), so its
workspace goes through the one volume engine (`kinematics.analyses.columns`) like every other
family's; a full-turn base joint makes it a solid of revolution measured by its (rho, z) profile.
The cell engine (`kinematics.analyses.serial_workspace`, proved bounds) stays for singular sets
and as an independent check. Singularity measure: iota_I = sigma_min / sigma_max of the
position Jacobian restricted to the task (the arm's plane for planar arms), 0 where it loses
rank (the inverse map is undefined: type I in Gosselin-Angeles' terms); iota_II = 1 (a serial arm
has no passive joints to release the tool).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.mechanisms.base import Assemblies, MarginFn, Mechanism, Velocity
from kinematics.model.robot import Robot

if TYPE_CHECKING:
    from kinematics.mechanisms.orientation import ToolOrientation
    from kinematics.mechanisms.serial.reach import Reach


class SerialArm(Mechanism):
    """An open chain loaded from a URDF; q are Pinocchio configurations (nq values per row)."""

    family = "serial"
    description = "open chain (compiled batched kinematics; reachability by a compiled search)"
    actuator_unit = "rad or m"
    assembly_modes = ("tool",)

    def __init__(self, robot: Robot, orientation: ToolOrientation | None = None) -> None:
        """orientation: a fixed tool orientation (`with_fixed_orientation`); None: the position alone."""
        from kinematics.generic.batched import PRISMATIC, compile_frame
        from kinematics.generic.serial import plane

        self.robot = robot
        self.name = robot.name
        self.orientation = orientation
        self.plane = plane(robot)
        if self.plane is not None:
            self.task_dim = 2
            self.task_axes = tuple("xyz"[k] for k in self.plane)
        prismatic = compile_frame(robot).kind == PRISMATIC
        # the unit of the Jacobian's columns: one unit when every chain joint shares it
        self.actuator_unit = "m" if prismatic.all() else "rad" if not prismatic.any() else "rad or m"

    def parameters(self) -> dict[str, Any]:
        r = self.robot
        out = {"frame": r.tool_frame, "joints": [d.name for d in r.dofs], "lower": r.lower.tolist(),
               "upper": r.upper.tolist()}
        if self.orientation is not None:
            out["orientation"] = self.orientation.as_dict()
        return out

    @cached_property
    def reach(self) -> Reach:
        """The reachability search of the tool frame (built on first use)."""
        from kinematics.mechanisms.serial.reach import Reach

        return Reach(self.robot, orientation=self.orientation)

    def reach_search(self) -> Reach:
        """`reach` (the `Mechanism` capability)."""
        return self.reach

    def reaching_jacobians(self, points: np.ndarray, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        """Position Jacobians at every configuration the search reaches task points (N, d) with:
        (N, K, d, n) [m/rad or m/m] over the chain joints and (N, K) whether seed k reached the
        point (`Reach.configurations`: each of the K seeds descended to its end, so a
        non-redundant arm's distinct solutions -- elbow up and down -- appear when seeds lie in
        their basins, and a redundant arm's K points of its self-motion set). With a fixed tool
        orientation: restricted to the joint velocities that keep it (`Reach.task_jacobians`)."""
        self.check_limits(limits)
        Q, ok = self.reach.configurations(self.reach.world(points))
        J = self.reach.task_jacobians(Q)[..., self._rows(), :]
        return np.where(ok[..., None, None], J, np.nan), ok

    def kernels(self) -> tuple[Any, ...]:
        from kinematics.mechanisms.serial import search

        return (search.search, search.chain_fk_many)

    def bounding_box(self, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        """The reach ball's box about the first joint (its disc's in the plane for planar arms) [m]."""
        self.check_limits(limits)
        return self.reach.box()

    def margin(self, branches: Sequence[str] | None = None, limits: str = "all") -> MarginFn:
        """points (N, task_dim) -> (N, 1): the reachability margin [m] of the union (a serial arm has
        no branches): tol - distance found, + a local room estimate when reached
        (`kinematics.mechanisms.serial.reach`)."""
        from kinematics.mechanisms.serial.reach import ReachMargin

        if branches:
            self.check_branches(branches)
        self.check_limits(limits)
        return ReachMargin(self.reach)

    def measure_zero(self) -> str | None:
        """Why the reachable set has zero area or volume (the tool point has fewer freedoms than the
        task space: `Reach.task_rank`), or None."""
        d, rank = self.task_dim, self.reach.task_rank()
        if rank >= d:
            return None
        s = self.reach.setup
        held = f"; {', '.join(s.fixed)} never move{'s' if len(s.fixed) == 1 else ''} it" if s.fixed else ""
        what = "a point" if rank == 0 else "a curve" if rank == 1 else "a surface"
        return (f"the frame {self.robot.tool_frame!r} has {rank} freedom{'s' if rank != 1 else ''} in a "
                f"{d}-D task space (its position Jacobian has rank {rank} at every configuration probed{held}): "
                f"it reaches {what}, of zero {'area' if d == 2 else 'volume'}")

    def _rows(self) -> list[int]:
        return list(self.plane) if self.plane is not None else [0, 1, 2]

    def fk(self, q: np.ndarray) -> Assemblies:
        from kinematics.generic.batched import batched_fk

        p = batched_fk(self.robot, np.atleast_2d(np.asarray(q, dtype=float))).position[:, self._rows()]
        return Assemblies(p[:, None, :], np.ones((len(p), 1), dtype=bool), ("tool",))

    def velocity(self, points: np.ndarray, q: np.ndarray) -> Velocity:
        from kinematics.generic.batched import batched_jacobian

        J = batched_jacobian(self.robot, np.atleast_2d(np.asarray(q, dtype=float)))[:, self._rows()]
        sv = np.linalg.svd(J, compute_uv=False)
        with np.errstate(invalid="ignore", divide="ignore"):
            iota = np.where(sv[:, 0] > 0, sv[:, -1] / sv[:, 0], 0.0)
        return Velocity(J, np.linalg.pinv(J), iota, np.ones_like(iota))


def with_fixed_orientation(robot: Robot, orientation: ToolOrientation) -> SerialArm:
    """`robot` as an open chain whose margin asks for its tool at `orientation` as well (any open
    chain, the SCARA's too: the closed forms know positions only)."""
    from kinematics.errors import UnsupportedRobotError

    if robot.loops is not None:
        raise UnsupportedRobotError(robot.name, "a fixed tool orientation is measured for open chains only; this "
                                                "robot has loop closures")
    if orientation.kind == "reference":
        raise UnsupportedRobotError(robot.name, "'reference' holds a closed loop's end effector at its reference "
                                                "rotation; for an open chain give 'rpy R P Y' or 'axis X Y Z'")
    return SerialArm(robot, orientation)
