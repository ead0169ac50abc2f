"""The mechanism interface: what every analysis asks of a robot.

A `Mechanism` describes a robot's task space (dimension, a bounding box) and, where the family
has them, vectorised maps over arrays of task points or actuator values:

* `margin(branches, limits)` -> a function points (N, d) [m] -> (N, B + 1) margins [m]: one
  column per branch (working mode, elbow) and a last one for their union (the maximum).
  Continuous, >= 0 exactly where the branch's inverse kinematics exists within the limits,
  roughly the distance to the nearest limit (a slack in metres), negative outside. Its zero set
  is the workspace boundary, which is what the volume engine integrates;
* `ik(points, limits)` -> every branch's actuator values and whether they exist / respect limits;
* `fk(q)` -> every assembly mode's task point;
* `velocity(points, q)` -> the forward Jacobian pdot = J qdot, its inverse and the scale-free
  singularity measures iota_I (the inverse map loses rank: an actuator velocity is undetermined
  by the task velocity) and iota_II (locked actuators no longer hold the task point), both in
  [0, 1] with 0 singular; type I, II or III (both) below `SINGULAR_TOL`;
* `singular_fields(points, limits)` -> signed fields whose sign changes between grid neighbours
  mark type I (per limb) and type II (per branch) loci, for scans;
* single-pose reports, what `kinematics ik|fk|jacobian` print for a mechanism with closed forms:
  `pose_ik(point)` (every branch, the limits each breaks, why a limb cannot reach),
  `pose_fk(q)` (every assembly mode, or why none exists) and `pose_jacobians(point, q)` (the
  loop equations' J_x, J_q and the singularity measures).

A mechanism that lacks one of these says so: calling it raises `MissingCapabilityError` naming
the capability, the purpose and what the mechanism does provide (`capabilities`). Analyses take a
mechanism (from `kinematics.mechanisms.mechanism_of(robot)`), never a robot family's parameters.
"""

from __future__ import annotations

from abc import ABC
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from kinematics.errors import InvalidInputError, MissingCapabilityError, UnknownChoiceError, UnknownModeError
from kinematics.generic.singularity import SINGULAR_TOL as SINGULAR_TOL
from kinematics.generic.singularity import SINGULARITY_TYPES as SINGULARITY_TYPES
from kinematics.generic.singularity import classify as classify

MarginFn = Callable[[np.ndarray], np.ndarray]
"""points (N, d) [m] -> (N, T) margins [m] (>= 0 inside target t)."""

UNION = "union"
"""The label of the union of every branch (the margin's last column)."""

CAPABILITIES = ("margin", "ik", "fk", "velocity", "singular_fields", "joint_values", "pose_ik", "pose_fk",
                "pose_jacobians", "joint_singularities", "reference_results", "paper_scan", "sweep_parameters",
                "reach_search")
"""The optional parts of the interface, by method name."""


def parallel_forward(Jx: np.ndarray, Jq: np.ndarray, iota_II: np.ndarray) -> np.ndarray:
    """The forward Jacobian J_x^-1 diag(J_q) of a parallel robot whose loop equations give
    J_x pdot = diag(J_q) qdot; NaN where J_x is singular (iota_II <= SINGULAR_TOL).

    Shapes: Jx S + (d, d), Jq S + (d,), iota_II S.
    """
    Jx = np.asarray(Jx, dtype=float)
    bad = ~(np.asarray(iota_II) > SINGULAR_TOL) | ~np.isfinite(Jx).all(axis=(-2, -1))
    eye = np.eye(Jx.shape[-1])
    safe = np.where(bad[..., None, None], eye, Jx)
    J = np.linalg.solve(safe, eye * np.where(np.isfinite(Jq), Jq, 0.0)[..., None, :])
    return np.where(bad[..., None, None], np.nan, J)


@dataclass(frozen=True)
class BranchIK:
    """Inverse kinematics of every branch at N task points.

    Attributes:
        q: (N, B, a) actuator values per branch (NaN where the branch does not exist) [m or rad].
        reachable: (N, B) the branch exists (limits ignored).
        within_limits: (N, B) it exists and respects the chosen limits.
    """

    q: np.ndarray
    reachable: np.ndarray
    within_limits: np.ndarray


@dataclass(frozen=True)
class Assemblies:
    """Forward kinematics of every assembly mode at N actuator vectors.

    Attributes:
        p: (N, A, d) task points [m] (NaN where that assembly does not exist).
        exists: (N, A) it exists.
        labels: the A assembly-mode labels.
    """

    p: np.ndarray
    exists: np.ndarray
    labels: tuple[str, ...]


@dataclass(frozen=True)
class Velocity:
    """First-order kinematics at N (task point, actuator values) pairs.

    Attributes:
        J: (N, d, a) forward Jacobian, pdot = J qdot [m/s per actuator unit/s] (inf/NaN where
            type II singular).
        J_inverse: (N, a, d) qdot = J_inverse pdot (inf/NaN where type I singular).
        iota_I, iota_II: (N,) scale-free measures in [0, 1] (1 for iota_II of a serial arm).
    """

    J: np.ndarray
    J_inverse: np.ndarray
    iota_I: np.ndarray
    iota_II: np.ndarray

    @property
    def types(self) -> np.ndarray:
        """(N,) 0 regular, 1 type I, 2 type II, 3 type III (`classify`)."""
        return classify(self.iota_I, self.iota_II)


@dataclass(frozen=True)
class SingularFields:
    """Signed fields for singular-locus scans at N task points.

    Attributes:
        margin: (N, B) the branches' margins [m] (no union column).
        limb: (N, k) per limb (or actuator): a sign change between neighbours crosses a type I
            locus of that limb (e.g. its IK discriminant [m^2]); >= 0 where the limb reaches.
        det: (N, B) per branch: a sign change crosses a type II locus (e.g. det of the rod
            directions); meaningful where every limb reaches.
    """

    margin: np.ndarray
    limb: np.ndarray
    det: np.ndarray


@dataclass(frozen=True)
class PoseIK:
    """Inverse kinematics at one task point, for a report.

    Attributes:
        q: (B, a) actuator values per branch (NaN where the branch does not exist) [m or rad].
        reachable: (B,) the branch exists (limits ignored).
        within_limits: (B,) it exists and respects every limit.
        violations: per branch, the limits it breaks in words (empty where it does not exist).
        limbs: per limb, {"limb": 1-based index, "reachable": bool, "reason": why it cannot reach
            (None when it can)}.
    """

    q: np.ndarray
    reachable: np.ndarray
    within_limits: np.ndarray
    violations: tuple[tuple[str, ...], ...]
    limbs: list[dict[str, Any]]

    @property
    def reason(self) -> str:
        """Why no branch exists: the unreachable limbs' reasons, joined."""
        return "; ".join(lb["reason"] for lb in self.limbs if lb["reason"])


@dataclass(frozen=True)
class PoseFK:
    """Forward kinematics at one actuator vector, for a report.

    Attributes:
        p: (A, d) the task point of each assembly mode [m] (NaN where it does not exist).
        exists: an assembly exists.
        violations: per assembly mode, the limits it breaks in words (empty when none exists).
        reason: why no assembly exists (None when one does).
    """

    p: np.ndarray
    exists: bool
    violations: tuple[tuple[str, ...], ...]
    reason: str | None


@dataclass(frozen=True)
class PoseJacobians:
    """The loop equations J_x pdot = diag(J_q) qdot at one pose.

    Attributes:
        Jx: (d, d) [m]. Jq: (a,) the diagonal of J_q.
        J: (a, d) the inverse Jacobian J_q^-1 J_x (qdot = J pdot; inf/NaN where type I singular).
        iota_I, iota_II: the scale-free singularity measures in [0, 1] (0 singular), scalars.
    """

    Jx: np.ndarray
    Jq: np.ndarray
    J: np.ndarray
    iota_I: np.ndarray
    iota_II: np.ndarray


def check_mechanism(mech: object, purpose: str) -> None:
    """Raise InvalidInputError unless `mech` is a `Mechanism` (what every analysis takes); a
    `Robot`, the usual slip, is told how to get one (`mechanism_of`)."""
    if isinstance(mech, Mechanism):
        return
    from kinematics.model.robot import Robot

    got = "a Robot: pass mechanism_of(robot)" if isinstance(mech, Robot) else f"got {type(mech).__name__}"
    raise InvalidInputError("mech", f"{purpose} takes a Mechanism (kinematics.mechanism_of(load_robot(...))); {got}")


class Mechanism(ABC):
    """A robot as the analyses see it (see the module docstring).

    Attributes:
        family: the family's key ("scara", "p2us", "delta", "serial", "closed-loop").
        closed_loop: the model has loop closures (a parallel mechanism).
        description: the family in words.
        name: the robot's (or design's) name.
        task_dim: 2 (planar) or 3.
        task_axes: names of the task coordinates, e.g. ("x", "y", "z").
        actuator_unit: "m" or "rad" (mixed chains: "m or rad").
        branch_kind: what a branch is called ("working mode", "elbow").
        branches: the branch labels, in the margin's column order.
        branch_legend: how to read a branch label.
        limit_sets: the accepted `limits` values; the first is the default.
        params: the family's design object (`P2USParams`, `DeltaParams`, `ScaraParams`), None
            for the generic families.
        assembly_modes: the labels of `fk`'s assembly modes.
        iota_I_label: how `iota_I` is computed, for reports (e.g. "iota_I = min |n.w|").
        limits_in_design: the limits are design parameters (`params`, read from the URDF's
            layout), which joint ranges given at loading (`load_robot(ranges=...)`) do not reach.
    """

    family: ClassVar[str]
    description: ClassVar[str]
    closed_loop: ClassVar[bool] = False
    name: str
    task_dim: int = 3
    task_axes: tuple[str, ...] = ("x", "y", "z")
    actuator_unit: str = "rad"
    branch_kind: str = "branch"
    branches: tuple[str, ...] = ()
    branch_legend: str = ""
    limit_sets: tuple[str, ...] = ("all",)
    params: Any = None
    assembly_modes: tuple[str, ...] = ()
    iota_I_label: str = "iota_I"
    limits_in_design: ClassVar[bool] = False

    # -- what the mechanism provides ---------------------------------------------------------
    @property
    def capabilities(self) -> frozenset[str]:
        """The optional methods this mechanism implements (a subset of CAPABILITIES)."""
        return frozenset(c for c in CAPABILITIES if getattr(type(self), c) is not getattr(Mechanism, c))

    def require(self, capability: str, purpose: str) -> None:
        """Raise MissingCapabilityError unless `capability` is provided."""
        if capability not in self.capabilities:
            raise MissingCapabilityError(self.name, capability, purpose, self.capabilities)

    def kernels(self) -> tuple[Any, ...]:
        """The compiled (Numba) kernels the margin and singular fields run on, for
        `kinematics.jit.cached` / `compiled` (a "compiling kernels" notice); none by default."""
        return ()

    def parameters(self) -> dict[str, Any]:
        """The design's parameters, JSON-ready (SI units)."""
        return {}

    def design_parameters(self) -> dict[str, Any]:
        """The numbers that define a family's design, read back from its URDF, for `kinematics info`
        (what the URDF's joint table does not show); empty for the generic families."""
        return {}

    def parameter_sources(self, urdf_path: str) -> dict[str, str]:
        """Parameter -> where its value comes from (a paper's table, ...) when the robot is a
        built-in design loaded from `urdf_path`; empty otherwise."""
        return {}

    def check_limits(self, limits: str) -> str:
        """`limits` if it is one of `limit_sets`; raises UnknownChoiceError otherwise."""
        if limits not in self.limit_sets:
            raise UnknownChoiceError(limits, self.limit_sets)
        return limits

    def check_branches(self, branches: Sequence[str] | None) -> tuple[str, ...]:
        """The branches asked for (all when None; one name alone is that branch), deduplicated;
        raises UnknownModeError."""
        if branches is None:
            return self.branches
        if isinstance(branches, str):  # "+-" is one label, not the labels "+" and "-"
            branches = [branches]
        for b in branches:
            if b not in self.branches:
                raise UnknownModeError(b, self.branches, self.name)
        if not branches:
            raise UnknownModeError("", self.branches, self.name)
        return tuple(dict.fromkeys(branches))

    def check_target(self, branch: str) -> tuple[str, ...]:
        """The branches behind one target: `branch` alone, or every branch for UNION; raises
        UnknownModeError listing UNION beside the branches, since it is a valid answer here."""
        if branch == UNION:
            return self.branches
        if branch not in self.branches:
            raise UnknownModeError(branch, (*self.branches, UNION))
        return (branch,)

    def bounding_box(self, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        """A box [m] containing every reachable task point under `limits`."""
        raise MissingCapabilityError(self.name, "bounding box", "a workspace scan", self.capabilities)

    def parallel_planes(self, branches: Sequence[str]) -> tuple[tuple[str, tuple[int, ...]], ...]:
        """Groups of `branches` whose end effector moves in different parallel planes (a planar
        motion with several assemblies, e.g. Gepetto's iso five-bars): (plane name, indices into
        `branches`) per plane, or () where every branch moves in one plane or space. Their regions
        do not overlap, so a workspace's union is the sum of the planes' unions."""
        return ()

    # -- optional capabilities ---------------------------------------------------------------
    def margin(self, branches: Sequence[str] | None = None, limits: str = "all") -> MarginFn:
        """points (N, d) -> (N, len(branches) + 1): each branch's margin [m], then the union's."""
        raise MissingCapabilityError(self.name, "margin", "a workspace measurement", self.capabilities)

    def ik(self, points: np.ndarray, limits: str = "all") -> BranchIK:
        """Every branch's inverse kinematics at task points (N, d) [m]."""
        raise MissingCapabilityError(self.name, "ik", "inverse kinematics", self.capabilities)

    def fk(self, q: np.ndarray) -> Assemblies:
        """Every assembly mode's task point for actuator values (N, a)."""
        raise MissingCapabilityError(self.name, "fk", "forward kinematics", self.capabilities)

    def velocity(self, points: np.ndarray, q: np.ndarray) -> Velocity:
        """Jacobians and singularity measures at task points (N, d) with actuator values (N, a)."""
        raise MissingCapabilityError(self.name, "velocity", "Jacobians", self.capabilities)

    def singular_fields(self, points: np.ndarray, limits: str = "all") -> SingularFields:
        """Signed type I / type II fields at task points (N, d) for locus scans."""
        raise MissingCapabilityError(self.name, "singular_fields", "a singular-locus scan", self.capabilities)

    def reference_pose(self) -> tuple[np.ndarray, str]:
        """A task point [m] and branch where the mechanism is assembled within its limits."""
        # named as itself: a generic closed loop has joint_values but no reference pose
        raise MissingCapabilityError(self.name, "reference_pose", "a reference pose", self.capabilities)

    def joint_values(self, point: np.ndarray, branch: str) -> dict[str, float]:
        """Every URDF joint's value (loops closed) with the task point at `point` [m] in `branch`."""
        raise MissingCapabilityError(self.name, "joint_values", "joint values at a task point", self.capabilities)

    def pose_ik(self, point: np.ndarray) -> PoseIK:
        """Every branch's inverse kinematics at one task point (d,) [m], with every limit, for a report."""
        raise MissingCapabilityError(self.name, "pose_ik", "inverse kinematics at a task point", self.capabilities)

    def pose_fk(self, q: np.ndarray) -> PoseFK:
        """Every assembly mode at one actuator vector (a,), with every limit, for a report."""
        raise MissingCapabilityError(self.name, "pose_fk", "forward kinematics of the actuators", self.capabilities)

    def pose_jacobians(self, point: np.ndarray, q: np.ndarray) -> PoseJacobians:
        """The loop-equation Jacobians at task point (d,) [m] with actuator values (a,)."""
        raise MissingCapabilityError(self.name, "pose_jacobians", "Jacobians at a task point", self.capabilities)

    def reach_search(self) -> Any:
        """The search that finds configurations reaching task points
        (`kinematics.mechanisms.serial.reach.Reach`), for a mechanism with no inverse kinematics
        per branch (a serial arm): its collisions are checked at the configurations it finds."""
        raise MissingCapabilityError(self.name, "reach_search", "configurations found by search", self.capabilities)

    def joint_singularities(self, angle_step: float | None = None) -> dict[str, Any]:
        """The singular set swept over a joint grid (`angle_step` [rad], None: the default), for
        a mechanism whose singularities are known in joint space (a planar 2R arm's theta2 = 0, pi):
        keys `singular_points` (N, d) [m], `singular_q` (N, n) [rad], `grid`, `min_radius` and the
        family's flags."""
        raise MissingCapabilityError(self.name, "joint_singularities", "a joint-space singular set",
                                     self.capabilities)

    def reference_results(self, urdf_path: str, limits: str, per_mode: dict[str, float],
                          union: float) -> dict[str, Any]:
        """Published results to set beside a measured workspace (per_mode: each branch's measure,
        union: theirs [m^3 or m^2]): JSON-ready keys for the workspace-volume report."""
        raise MissingCapabilityError(self.name, "reference_results", "a comparison with published results",
                                     self.capabilities)

    def reference_lines(self, results: dict[str, Any]) -> list[str]:
        """Human lines of `reference_results` (none for a mechanism without them)."""
        return []

    def paper_scan(self) -> dict[str, Any]:
        """The paper's own singularity scan of this design, as published (counts and poses)."""
        raise MissingCapabilityError(self.name, "paper_scan", "the paper's singularity scan", self.capabilities)

    def sweep_parameters(self) -> Any:
        """The design parameters a design sweep (`kinematics.analyses.sweep`) varies."""
        raise MissingCapabilityError(self.name, "sweep_parameters", "a design sweep", self.capabilities)

    # -- derived -----------------------------------------------------------------------------
    def branch_velocity(self, points: np.ndarray, branch: str, limits: str = "all") -> tuple[Velocity, np.ndarray]:
        """`velocity` in one branch at task points (N, d): (Velocity, (N,) inside the branch
        within `limits`). Outside, the Jacobians are NaN."""
        return self.branch_velocities(points, [branch], limits)[0]

    def branch_velocities(self, points: np.ndarray, branches: Sequence[str], limits: str = "all"
                          ) -> list[tuple[Velocity, np.ndarray]]:
        """`branch_velocity` of each distinct branch, in order, from one inverse kinematics of
        every branch (`ik` solves them all at once: `branch_velocity` per branch solves them B times)."""
        self.require("ik", "Jacobians at task points")
        self.require("velocity", "Jacobians at task points")
        chosen = self.check_branches(branches if isinstance(branches, str) else list(branches))
        res = self.ik(points, limits)
        points = np.asarray(points, dtype=float)
        n, d, a = len(points), self.task_dim, res.q.shape[-1]
        out = []
        for b in chosen:
            k = self.branches.index(b)
            q = res.q[:, k]
            ok = res.within_limits[:, k] & np.isfinite(q).all(axis=-1)
            J, Ji = np.full((n, d, a), np.nan), np.full((n, a, d), np.nan)
            iota_I, iota_II = np.full(n, np.nan), np.full(n, np.nan)
            if ok.any():  # only where the branch exists: outside it the Jacobians are NaN anyway
                with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                    v = self.velocity(points[ok], q[ok])
                J[ok], Ji[ok], iota_I[ok], iota_II[ok] = v.J, v.J_inverse, v.iota_I, v.iota_II
            out.append((Velocity(J, Ji, iota_I, iota_II), ok))
        return out

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}: {self.description}>"
