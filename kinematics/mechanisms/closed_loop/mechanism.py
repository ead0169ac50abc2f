"""A URDF + loop sidecar with no closed forms as a `Mechanism`, through the batched closed-loop
solver (`kinematics.generic.loop_batch.LoopBatch`).

Branches are the solver's atlas: the working modes found at the sidecar's reference position,
labelled by the signs of the loop Jacobian's square sub-determinants that contain an actuator
(docs/closed-loops.md). Task space: the platform position for translational mechanisms, the
in-plane position for planar ones, and for a mechanism with six actuators that turn its end
effector, its position with a held rotation (`orientation`: the constant-orientation workspace of a
6-DOF leg or platform; velocities and singular loci are not done for it). Other mechanisms whose
task needs orientation are refused when a capability is first used. Margins come from the URDF's
joint limits ("all", or "actuators" only), minus the least-squares residual where a branch has no
solution; where no joint limit
binds (e.g. the five-bar's continuous joints) the slack is capped at the robot's size, so the
margin jumps at the reach boundary instead of falling to 0 there (its sign stays right).

Two honest limits, stated where they are used: the bounding box is sampled (the end effector's
own chain within its joint limits, padded by 5 %), not proved; and the solver evaluates ~10^3
task points per second on 2 cores, so a 3D workspace volume takes tens of minutes (planar ones
about a minute). Singular fields come from `kinematics.generic.loop_singular` (type I per
labelling block, type II per branch; what they cannot see is stated there).
Forward kinematics goes through the Pinocchio closed-loop solver (one assembly, reached from the
reference configuration).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

import numpy as np

from kinematics.errors import UnsupportedRobotError
from kinematics.mechanisms.base import Assemblies, BranchIK, MarginFn, Mechanism, SingularFields, Velocity
from kinematics.mechanisms.orientation import ToolOrientation
from kinematics.model.robot import Robot

_AXES = "xyz"

QUERY_POINTS = 8
"""A query of at most this many points (the CLI's `ik`, a pose, a view) where the batched search
misses a branch is solved again by continuation from the reference position (`_search`); a grid's
points have their neighbours instead, and most of them lie outside, where it would cost."""

CONTINUATION_STEPS = 16
"""Points of that continuation along the segment from the reference position to the target."""

MAX_TASK_DIM = 3
"""The batched solver's task: the end effector's position, one coordinate per actuator."""

HELD_ACTUATORS = 6
"""Actuators of a mechanism whose end effector is held at a rotation: 3 for its position, 3 for the
rotation held."""

BATCHED = ("margin", "ik", "velocity", "singular_fields")
"""The capabilities that run on the batched solver (and so need a task of at most MAX_TASK_DIM
coordinates, or a held orientation)."""

HELD_ROTATION_TOL = 1e-8
"""`fk` with a held orientation: the largest entry of R - R_held (~ the angle [rad]) of a pose on
the held set (the closed-loop solver closes to ~1e-10)."""

NOT_HELD = frozenset({"velocity", "singular_fields"})
"""Capabilities a held orientation does not have: its Jacobians relate six actuator rates to the
whole twist, not to the position alone."""


class GenericClosedLoop(Mechanism):
    """Any closed-loop robot (URDF tree + loop sidecar)."""

    family = "closed-loop"
    description = "closed-loop model (generic batched solver)"
    closed_loop = True
    actuator_unit = "rad or m"
    branch_kind = "working mode"
    branch_legend = ("working mode: one sign per labelling block of the loop Jacobian (a square sub-determinant "
                     "containing an actuator), as found at the sidecar's reference position; 'union': any mode")
    limit_sets = ("all", "actuators")
    assembly_modes = ("reached from the reference",)

    def __init__(self, robot: Robot, orientation: ToolOrientation | None = None) -> None:
        """orientation: hold the end effector at this rotation (six actuators; "rotation" or
        "reference" kind), the task being its position; None: the position alone."""
        self.robot = robot
        self.name = robot.name
        self.orientation = orientation
        self._continued: dict[bytes, Any] = {}  # `_continuation`'s last answers, by target
        # the unit of J's columns, one per actuator: one unit when every actuator shares it (as
        # SerialArm), so dexterity notes a mixed J only for a mechanism that has one
        kinds = {d.name: d.kind for d in robot.dofs}
        prismatic = [kinds.get(a) == "prismatic" for a in (robot.loops.actuated if robot.loops else ())]
        if prismatic:
            self.actuator_unit = "m" if all(prismatic) else "rad" if not any(prismatic) else "rad or m"

    @functools.cached_property
    def batch(self) -> Any:
        """The compiled batched solver (built on first use: compiles kernels, finds the branches).

        Raises:
            UnsupportedRobotError: more actuators than position coordinates (`check_task`).
            SingularConfigurationError: the pose the solver picks its task at is a type II
                singularity (the message says which pose).
        """
        from kinematics.errors import SingularConfigurationError
        from kinematics.generic.closedloop import ClosedLoop
        from kinematics.generic.loop_batch import loop_batch

        self.check_task()
        o = self.orientation
        try:
            batch = loop_batch(self.robot, None if o is None else "reference" if o.kind == "reference" else o.matrix)
        except SingularConfigurationError as exc:
            where = ClosedLoop(self.robot).assembly.description  # cached: the pose the solver used
            raise SingularConfigurationError(
                f"{self.name}: choosing the task space at {where}",
                f"{exc} (the batched solver reads what the actuators move from the end effector "
                f"{self.robot.tool_frame!r} there; --tool-frame chooses another)") from None
        return batch

    @property
    def held(self) -> ToolOrientation | None:
        """The rotation the end effector is held at, a "reference" resolved to its matrix (builds the
        solver), or None."""
        o = self.orientation
        if o is None or o.kind != "reference":
            return o
        from scipy.spatial.transform import Rotation

        R = np.asarray(self.batch.held_orientation)
        rpy = Rotation.from_matrix(R).as_euler("xyz")
        return ToolOrientation("rotation", R, "reference (rpy " + " ".join(f"{v:.6g}" for v in rpy) + ")")

    @property
    def capabilities(self) -> frozenset[str]:
        """As `Mechanism.capabilities`, less NOT_HELD with a held orientation."""
        caps = super().capabilities
        return caps - NOT_HELD if self.orientation is not None else caps

    def check_task(self) -> None:
        """The batched solver's task is the end effector's position, one coordinate per actuator
        (at most MAX_TASK_DIM), or with a held orientation HELD_ACTUATORS actuators: raise
        UnsupportedRobotError, saying so, for a robot with more actuators, whose end-effector
        position is redundant, and for a held orientation the robot cannot take."""
        loops = self.robot.loops
        n = len(loops.actuated) if loops else 0
        o = self.orientation
        if o is not None:
            if o.kind == "axis":
                raise UnsupportedRobotError(self.name, "a closed loop's end effector is held at a whole rotation "
                                                       "('rpy R P Y' or 'reference'), not at a tool axis alone")
            if n != HELD_ACTUATORS:
                raise UnsupportedRobotError(self.name, (
                    f"holding the end effector's orientation leaves its {MAX_TASK_DIM} position coordinates to "
                    f"exactly {HELD_ACTUATORS} actuators ({MAX_TASK_DIM} + 3); this robot has {n}"))
            return
        if loops is not None and n > MAX_TASK_DIM:
            shown = ", ".join(loops.actuated[:8]) + (", ..." if n > 8 else "")
            raise UnsupportedRobotError(
                self.name,
                f"{n} actuators ({shown}) for the {MAX_TASK_DIM} coordinates of the end effector "
                f"{self.robot.tool_frame!r}'s position: more actuators than task coordinates, so that position is "
                f"redundant (up to {n - MAX_TASK_DIM} actuator freedom(s) beyond it), and the batched closed-loop "
                "solver behind workspaces, IK and singular loci needs exactly one task coordinate per actuator, at "
                f"most the {MAX_TASK_DIM} of a position (orientation coordinates are not done)"
                + (f"; with {HELD_ACTUATORS} actuators, `workspace-volume` and `ik` take the end effector held at a "
                   "rotation: --orientation 'rpy R P Y' or 'reference' (library: mechanism_of(robot, "
                   "ToolOrientation...))" if n == HELD_ACTUATORS else ""))

    @property
    def branches(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(self.batch.branch_names)

    @property
    def task_dim(self) -> int:  # type: ignore[override]
        return int(self.batch.task_dim)

    @property
    def task_axes(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(_AXES[k] for k in self.batch.task_axes)

    def kernels(self) -> tuple[Any, ...]:
        from kinematics.generic.loop_batch import kernels

        return kernels()

    @functools.cached_property
    def plane(self) -> Any:
        """`kinematics.generic.motion_plane.MotionPlane` of the end effector's closed motion, or None
        (spatial)."""
        from kinematics.generic.motion_plane import motion_plane

        return motion_plane(self.robot)

    def parallel_planes(self, branches: Sequence[str]) -> tuple[tuple[str, tuple[int, ...]], ...]:
        """`Mechanism.parallel_planes`: a planar motion's branches grouped by the end effector's
        coordinate along the plane's normal at each branch's atlas pose (equal to 1e-6 of the
        robot's size); () when they share one plane."""
        if self.plane is None:
            return ()
        b = self.batch
        names = self.branches
        idx = [names.index(x) for x in branches]
        offsets = b.end_effector_positions(b.atlas[idx])[:, self.plane.normal]
        tol = 1e-6 * float(b.scale)
        groups: list[tuple[float, list[int]]] = []
        for k, off in enumerate(offsets):
            for g in groups:
                if abs(g[0] - off) <= tol:
                    g[1].append(k)
                    break
            else:
                groups.append((float(off), [k]))
        if len(groups) < 2:
            return ()
        axis = _AXES[self.plane.normal]
        return tuple((f"plane {axis}={off + 0.0:.6g}", tuple(g)) for off, g in sorted(groups, reverse=True))

    def parameters(self) -> dict[str, Any]:
        loops = self.robot.loops
        out: dict[str, Any] = {"closures": len(loops.closures) if loops else 0,
                               "actuated": list(loops.actuated) if loops else [], "end_effector": self.robot.tool_frame}
        if self.orientation is not None:  # a "reference" once resolved (the solver built)
            held = self.held if "batch" in self.__dict__ else self.orientation
            out["orientation"] = held.as_dict() if held is not None else None
        if self.plane is not None:
            # an area is measured in this plane; another assembly mode can move in a parallel one
            i, j = (_AXES[a] for a in self.plane.axes)
            out["plane"] = f"{i}-{j} at {_AXES[self.plane.normal]} = {self.plane.offset:.6g} m"
            planes = self.parallel_planes(self.branches) if "batch" in self.__dict__ else ()
            if planes:
                out["parallel_planes"] = (", ".join(name for name, _ in planes) + ": assemblies in parallel planes; "
                                          "the union is the sum of the planes' areas (they do not overlap)")
        return out

    def _require_actuator_ranges(self, purpose: str = "a workspace") -> None:
        loops = self.robot.loops
        self.robot.require_ranges(loops.actuated if loops else (), purpose)

    def require(self, capability: str, purpose: str) -> None:
        """As `Mechanism.require`; what runs on the batched solver also needs at most MAX_TASK_DIM
        actuators, and a margin every actuator's range (both checked here, before the solver is
        compiled, so either is said at once). With a held orientation NOT_HELD is refused saying why."""
        if self.orientation is not None and capability in NOT_HELD:
            raise UnsupportedRobotError(self.name, f"{purpose} cannot be computed with the end effector held at a "
                                                   "rotation: its six actuators drive the whole pose, and velocities "
                                                   "and singular loci of the position alone are not done")
        super().require(capability, purpose)
        if capability in BATCHED:
            try:
                self.check_task()
            except UnsupportedRobotError as exc:
                raise UnsupportedRobotError(self.name, f"{purpose} cannot be computed: {exc.problem}") from None
        if capability == "margin":
            self._require_actuator_ranges(purpose)

    def bounding_box(self, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        """Sampled, not proved (module docstring).

        Raises:
            MissingRangeError: an actuated joint has no range.
        """
        self.check_limits(limits)
        self._require_actuator_ranges()
        lo, hi = self.batch.bounding_box()
        return np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)

    def margin(self, branches: Sequence[str] | None = None, limits: str = "all") -> MarginFn:
        self.check_limits(limits)
        self._require_actuator_ranges()
        chosen = self.check_branches(branches)
        names = self.branches
        f = self.batch.margin_function([names.index(b) for b in chosen], limits)
        cap = float(self.batch.scale)

        def margin(points: np.ndarray) -> np.ndarray:
            # a branch with no binding joint limit has an infinite slack: cap it at the robot's
            # size (the sign, which is what the volume engine brackets, is unchanged)
            return np.minimum(f(points), cap)

        return margin

    def _search(self, points: np.ndarray) -> Any:
        """The batched solver's branches at points (N, d); for a query of at most QUERY_POINTS
        points, each point where a branch is missing is solved again by continuation along the
        segment from the reference position (CONTINUATION_STEPS targets, each warm-started from the
        last), and the branches it finds are added. A cold point has no neighbour to start from:
        the atlas starts and restarts can all miss where the continuation does not (Gepetto's
        five-bar fixture at (0.2109, -0.2188): none of its four modes cold, all four continued).
        The continuation can still miss a branch whose region the segment does not cross."""
        sol = self.batch.ik(points)
        if len(sol.found) > QUERY_POINTS or sol.found.all():
            return sol
        x, found, residual, margin, end = (np.array(a) for a in (sol.x, sol.found, sol.residual, sol.margin, sol.end))
        p = np.atleast_2d(np.asarray(points, dtype=float))  # (checked by the search above)
        for i in np.flatnonzero(~found.all(axis=1)):
            step = self._continuation(p[i])
            new = step.found[0] & ~found[i]
            x[i, new], residual[i, new], margin[i, new], end[i, new] = (
                step.x[0, new], step.residual[0, new], step.margin[0, new], step.end[0, new])
            found[i] |= new
        return sol._replace(x=x, found=found, residual=residual, margin=margin, end=end)

    def _continuation(self, point: np.ndarray) -> Any:
        """The batched solver's branches at `point` (d,) reached by continuation from the reference
        position (`_search`). The last QUERY_POINTS answers are kept: a query repeated (the CLI's
        `ik`, then `joint_values` for each mode it found) is not continued again where a mode is
        absent (16 solves each time)."""
        key = point.tobytes()
        if key not in self._continued:
            start = self.batch.reference_point
            for t in np.linspace(0.0, 1.0, CONTINUATION_STEPS + 1)[1:]:
                step = self.batch.ik((start + t * (point - start))[None])
            if len(self._continued) >= QUERY_POINTS:
                del self._continued[next(iter(self._continued))]  # the oldest
            self._continued[key] = step
        return self._continued[key]

    def _solve(self, points: np.ndarray, limits: str) -> tuple[Any, np.ndarray]:
        self.check_limits(limits)
        sol = self._search(points)
        x = np.nan_to_num(sol.x)
        within = sol.found & (self.batch.limit_margin(x.reshape(-1, x.shape[-1]), limits).reshape(sol.found.shape) >= 0)
        return sol, within

    def ik(self, points: np.ndarray, limits: str = "all") -> BranchIK:
        sol, within = self._solve(points, limits)
        q = sol.x[..., self.batch.actuated]
        return BranchIK(np.where(sol.found[..., None], q, np.nan), sol.found.copy(), within)

    def joint_values(self, point: np.ndarray, branch: str) -> dict[str, float]:
        """Every URDF joint's value [rad or m] (loops closed) with the end effector at `point` [m]
        in `branch` (`joint_value_rows`). Raises InvalidInputError where the branch has no
        solution there."""
        from kinematics.errors import InvalidInputError

        row = self.joint_value_rows(np.asarray(point, dtype=float)[None], branch)[0]
        if not np.isfinite(row).all():
            raise InvalidInputError("point", f"{np.asarray(point).tolist()} is not reached in working mode {branch}")
        return dict(zip(self.robot.joint_names, row.tolist(), strict=True))

    def joint_value_rows(self, points: np.ndarray, branch: str) -> np.ndarray:
        """(N, n) every joint's value [rad or m], URDF joint order (loops closed), with the end
        effector at points (N, d) [m] in `branch`: the batched solver's solution (the margin's);
        NaN rows where the branch has none (limits not applied)."""
        b = self.branches.index(self.check_branches([branch])[0])
        sol = self._search(np.atleast_2d(np.asarray(points, dtype=float)))
        return np.where(sol.found[:, b, None], sol.x[:, b], np.nan)

    def velocity(self, points: np.ndarray, q: np.ndarray) -> Velocity:
        """At each point (N, d), the branch whose actuator values are nearest `q` (N, a).

        Raises:
            InvalidInputError: points or q of the wrong shape, or not finite.
        """
        self.require("velocity", "velocities")  # not with a held orientation
        p = np.atleast_2d(np.asarray(points, dtype=float))
        q = self._actuator_rows(q, len(p))  # before the solve, which a malformed q would waste
        d, a = self.task_dim, q.shape[1]
        if not len(p):
            return Velocity(np.zeros((0, d, a)), np.zeros((0, a, d)), np.zeros(0), np.zeros(0))
        sol = self._search(p)
        qa = sol.x[..., self.batch.actuated]  # (N, B, a)
        dist = np.where(sol.found, np.linalg.norm(qa - q[:, None, :], axis=-1), np.inf)
        pick = np.argmin(dist, axis=1)
        rows = np.arange(len(p))
        x = np.where(np.isfinite(dist[rows, pick])[:, None], sol.x[rows, pick], np.nan)
        forward, inverse = self.batch.jacobians(p, x)
        s = self.batch.singularities(p, x)
        return Velocity(forward[:, 0], inverse[:, 0], s.iota_I[:, 0], s.iota_II[:, 0])

    def singular_fields(self, points: np.ndarray, limits: str = "all") -> SingularFields:
        """Type I per labelling block and type II per branch, signed (`kinematics.generic.loop_singular`)."""
        from kinematics.generic.loop_singular import loop_fields

        self.require("singular_fields", "singular loci")  # not with a held orientation
        self.check_limits(limits)
        f = loop_fields(self.batch, points, limits)
        return SingularFields(f.margin, f.limb, f.det)

    def fk(self, q: np.ndarray) -> Assemblies:
        """The end effector's task point (N, 1, d) [m] at actuator values q (N, a) (one (a,) row
        is N = 1), on the assembly the continuation from the reference reaches; NaN where it finds
        none. d is `task_axes` (the coordinates `ik` and `margin` take) for a robot with at most
        MAX_TASK_DIM actuators, else the position's three. With a held orientation, also NaN where
        the end effector's rotation there is not the one held (HELD_ROTATION_TOL): such actuator
        values leave the held set.

        Raises:
            InvalidInputError: q is not (N, a) finite values.
        """
        from kinematics.errors import KinematicsError
        from kinematics.generic.closedloop import ClosedLoop

        loop = ClosedLoop(self.robot)
        q = self._actuator_rows(q, None)
        held = self.held
        R = None if held is None else held.matrix
        loops = self.robot.loops
        axes = list(self.batch.task_axes) if loops is not None and len(loops.actuated) <= MAX_TASK_DIM else [0, 1, 2]
        p = np.full((len(q), 1, len(axes)), np.nan)
        for k, row in enumerate(q):
            try:
                sol = loop.solve(row)
            except KinematicsError:  # the inputs are checked: no assembly reached there
                continue
            if R is not None and np.abs(sol.pose.rotation - R).max() > HELD_ROTATION_TOL:
                continue
            p[k, 0] = sol.pose.translation[axes]
        return Assemblies(p, np.isfinite(p).all(axis=-1), self.assembly_modes)

    def _actuator_rows(self, q: np.ndarray, n: int | None) -> np.ndarray:
        """q as (N, a) finite actuator values (one (a,) row is N = 1; N = n when given)."""
        from kinematics.errors import InvalidInputError
        from kinematics.inputs import finite_vectors

        names = self.robot.loops.actuated if self.robot.loops else ()
        a = finite_vectors(q, len(names), "q", f"actuator values ({', '.join(names)})")
        a = a.reshape(1, -1) if a.ndim <= 1 else a
        if a.ndim != 2 or (n is not None and len(a) != n):
            raise InvalidInputError("q", f"expected shape ({'N' if n is None else n}, {len(names)}) actuator values "
                                         f"({', '.join(names)}), got {np.shape(q)}")
        return a
