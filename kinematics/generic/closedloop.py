"""A generic closed-loop solver on the Pinocchio model: any URDF tree plus a loop sidecar.

Each closure of the sidecar becomes a Pinocchio constraint model (`PointAnchorConstraintModel`
for `point`, `FrameAnchorConstraintModel` for `6d`). Their stacked errors e(q) and Jacobian K(q)
= de/dv (`getConstraintsJacobian`) drive a Newton iteration on the passive joints, with the
actuated joints held:

    dv_p = -lstsq(K_p, e),   q <- integrate(q, [0; dv_p])   (backtracking if |e| grows)

Newton from an arbitrary start diverges or lands on another assembly, so the default start is
the sidecar's `reference` configuration (closed first where it is open: `assembly.assemble`),
moved to the target by predictor-corrector continuation:
the actuated values walk there in steps; each step is predicted along the loop manifold's
tangent (dv_p = -K_p^+ K_a da), capped so the passive joints move at most MAX_PASSIVE_STEP,
corrected by Newton, and rejected (step halved) if the correction drifts far from the prediction,
the sign of a jump to another branch. A path that crosses a singularity may still end on the
other branch; a warm start `q0` from a nearby solution skips the walk. Where the continuation gets
stuck, `solve(..., fallback=True)` closes the loops by `assembly.assemble` with the actuators held
at the target (projection, then restarts: possibly another assembly mode). Non-convergence raises
ConvergenceError.

With the loops closed, K_a v_a + K_p v_p = 0 gives v_p = -K_p^+ K_a v_a, and the end-effector's
world-aligned twist is (J_a - J_p K_p^+ K_a) v_a: the constrained Jacobian.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.errors import (
    ConvergenceError,
    InvalidInputError,
    SingularConfigurationError,
    UnsupportedRobotError,
)
from kinematics.model.loops import LoopSpec
from kinematics.model.robot import Robot, matrix

if TYPE_CHECKING:  # pragma: no cover
    from kinematics.generic.assembly import Assembly

TOLERANCE = 1e-12
"""Default loop-closure tolerance: largest constraint error [m] (or [rad] for 6d closures)."""

MAX_PASSIVE_STEP = 0.1
"""Continuation: largest predicted passive-joint change per step [rad or m]."""

MAX_DRIFT = 0.5
"""Continuation: a step is rejected when Newton moves the prediction by more than this fraction
of the predicted passive change (a sign that it is converging to another branch)."""

RANK_RTOL = 1e-10
"""K_p counts as rank deficient when sigma_min <= RANK_RTOL * sigma_max."""

FREE_RTOL = 1e-8
"""The end effector counts as free with the actuators locked when |J_p N| > FREE_RTOL |J_p|
(N: orthonormal basis of null(K_p)). N is accurate to ~eps |K_p| / (smallest non-zero singular
value of K_p), so an idle freedom leaves |J_p N| / |J_p| ~ 1e-16 (measured <= 5e-17 on the RSSR
test model); 1e-8 keeps eight decades of margin below a motion that would move the end effector."""


class LoopSolution(NamedTuple):
    """A closed configuration.

    Attributes:
        q: full Pinocchio configuration.
        values: one value per degree of freedom (model order).
        pose: world placement of the end-effector frame.
        residual: largest constraint error at q [m].
        iterations: Newton iterations spent (all continuation steps together).
        held: closed by `solve`'s fallback (the actuators held), not by the continuation: possibly
            another assembly mode than a path from the reference reaches.
    """

    q: np.ndarray
    values: np.ndarray
    pose: pin.SE3
    residual: float
    iterations: int
    held: bool = False


class ClosedLoop:
    """The loop-closure constraints of a robot and the solvers built on them.

    Not thread-safe (it owns Pinocchio Data); make one per thread.
    """

    def __init__(self, robot: Robot) -> None:
        if robot.loops is None:
            raise UnsupportedRobotError(robot.name, "no loop-closure sidecar (<name>.loops.yaml) next to its URDF")
        self.robot = robot
        self.spec: LoopSpec = robot.loops
        model = robot.model
        self.model = model
        self.data = model.createData()
        self.models = pin.StdVec_ConstraintModel()
        for c in self.spec.closures:
            f1 = model.frames[robot.frame_id(c.frame1)]
            f2 = model.frames[robot.frame_id(c.frame2)]
            cls = pin.PointAnchorConstraintModel if c.type == "point" else pin.FrameAnchorConstraintModel
            self.models.append(pin.ConstraintModel(cls(model, f1.parentJoint, f1.placement, f2.parentJoint, f2.placement)))
        self.datas = pin.StdVec_ConstraintData()
        for cm in self.models:
            self.datas.append(cm.createData())
        names = robot.joint_names
        self.actuated_dofs = np.array([names.index(a) for a in self.spec.actuated])
        self.passive_dofs = np.array([i for i in range(robot.nv) if i not in set(self.actuated_dofs.tolist())])
        self.actuated_v = np.array([robot.dofs[i].idx_v for i in self.actuated_dofs])
        self.passive_v = np.array([robot.dofs[i].idx_v for i in self.passive_dofs])
        self.ee = robot.frame_id(self.spec.end_effector)

    @property
    def n_constraints(self) -> int:
        """Number of scalar loop-closure equations."""
        return sum(c.size for c in self.spec.closures)

    # -- residual --------------------------------------------------------------------------------
    def residual(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Stacked constraint errors e(q) and their Jacobian K = de/dv (n_constraints x nv)."""
        pin.forwardKinematics(self.model, self.data, q)
        pin.computeJointJacobians(self.model, self.data, q)
        errors = []
        for cm, cd in zip(self.models, self.datas, strict=True):
            cm.calc(self.model, self.data, cd)
            errors.append(np.array(cd.extract().constraint_position_error))
        K = matrix(pin.getConstraintsJacobian(self.model, self.data, self.models, self.datas), self.model.nv)
        return np.concatenate(errors), K.copy()

    # -- configurations --------------------------------------------------------------------------
    def _with_actuated(self, q: np.ndarray, actuated: np.ndarray) -> np.ndarray:
        values = self.robot.values_from_configuration(q)
        values[self.actuated_dofs] = actuated
        return self.robot.configuration(values)

    @functools.cached_property
    def assembly(self) -> Assembly:
        """The closed configuration every default starts from: the sidecar's reference (the
        neutral pose where it names no value), closed by `kinematics.generic.assembly.assemble`
        where it is open (its `description` says which).

        Raises:
            AssemblyError: no closed configuration was found.
        """
        from kinematics.generic.assembly import assemble

        return assemble(self.robot, loop=self)

    @property
    def reference(self) -> np.ndarray:
        """`assembly.q`: a closed configuration at (or found from) the sidecar's reference."""
        return self.assembly.q

    def newton(self, q: np.ndarray, tol: float = TOLERANCE, max_iter: int = 30,
               free: np.ndarray | None = None) -> tuple[np.ndarray, float, int]:
        """Close the loops from `q` by moving the passive joints only (or the velocity indices
        `free`): Gauss-Newton with minimum-norm steps, halved while the residual grows.

        Returns (q, residual, iterations); the residual is above `tol` if it failed.
        """
        cols = self.passive_v if free is None else np.asarray(free, dtype=int)
        e, K = self.residual(q)
        err = float(np.max(np.abs(e))) if e.size else 0.0
        it = 0
        while err > tol and it < max_iter:
            it += 1
            dv_p = -np.linalg.lstsq(K[:, cols], e, rcond=None)[0]
            step = 1.0
            while True:
                v = np.zeros(self.model.nv)
                v[cols] = step * dv_p
                q_new = pin.integrate(self.model, q, v)
                e_new, K_new = self.residual(q_new)
                err_new = float(np.max(np.abs(e_new)))
                if err_new < err or step < 1e-3:
                    break
                step *= 0.5
            if not err_new < err:
                break  # stalled
            q, e, K, err = q_new, e_new, K_new, err_new
        return q, err, it

    def solve(self, actuated: np.ndarray, q0: np.ndarray | None = None, tol: float = TOLERANCE,
              max_iter: int = 30, fallback: bool = False) -> LoopSolution:
        """Passive joints, full configuration and end-effector pose for given actuated values.

        Args:
            actuated: one value per actuated joint, in the sidecar's order [m or rad].
            q0: warm start (a closed configuration near the answer); default: continuation from
                the sidecar's reference configuration.
            fallback: where the continuation gets stuck, close the loops by `assembly.assemble`
                with the actuators held at `actuated` (projection, then restarts) instead of
                raising: a closed configuration at those values, possibly of another assembly mode
                than a path from the reference reaches.

        Raises:
            ConvergenceError: the loops could not be closed to `tol` (no assembly there, or the
                continuation met a singularity).
        """
        target = np.asarray(actuated, dtype=float).reshape(-1)
        if target.size != len(self.actuated_dofs):
            raise InvalidInputError("actuated values", f"expected {len(self.actuated_dofs)} "
                                    f"({', '.join(self.spec.actuated)}), got {target.size}")
        if not np.all(np.isfinite(target)):
            raise InvalidInputError("actuated values", "must be finite")
        total = 0
        if q0 is not None:
            q, err, it = self.newton(self._with_actuated(self.robot.check_configuration(q0), target), tol, max_iter)
            total += it
            if err <= tol:
                return self._solution(q, err, total)
        # Continuation from the reference configuration (predictor-corrector).
        q = self.reference
        start = self.robot.values_from_configuration(q)[self.actuated_dofs]
        q, err, it = self.newton(q, tol, max_iter)
        total += it
        if err > tol:
            raise ConvergenceError(f"closing the loops at {self.assembly.description}", total, err, tol)
        s, ds = 0.0, 0.25
        why: str | None = None  # the last refused step's reason, where its residual met the tolerance
        while s < 1.0:
            if ds < 1e-6:
                what = (f"closing the loops at actuated values {target.tolist()} (continuation from "
                        f"{self.assembly.description}, at actuated values {np.round(start, 6).tolist()}, stuck "
                        f"{s:.4f} of the way" + (", and projection with the actuators held found no closed pose"
                                                 if fallback else "") + ": no assembly there, or a singularity on "
                        "the way)")
                if not fallback:
                    raise ConvergenceError(what, total, err, tol, why)
                return self._assemble_held(target, total, what, err, tol)
            s_next = min(1.0, s + ds)
            step = self._predict(q, (s_next - s) * (target - start))
            if step is None:
                why = "the passive joints' predicted step stayed above its limit however short (a singularity)"
                ds *= 0.5
                continue
            q_pred, moved = step
            q_try, err, it = self.newton(q_pred, tol, max_iter)
            total += it
            drift = float(np.max(np.abs(pin.difference(self.model, q_pred, q_try))))
            if err <= tol and drift <= MAX_DRIFT * max(moved, 1e-9):
                q, s = q_try, s_next
                ds = min(1.0, 2 * ds)
            else:
                why = None if err > tol else (f"its last step closed the loops (residual {err:.3g}) {drift:.3g} from "
                                              f"its prediction, over {MAX_DRIFT:g} x the predicted move ({moved:.3g}): "
                                              "a jump to another assembly, refused")
                ds *= 0.5
        return self._solution(q, err, total)

    def _assemble_held(self, target: np.ndarray, total: int, what: str, err: float, tol: float) -> LoopSolution:
        """The fallback of a stuck continuation: `assemble` from the reference pose with the
        actuators moved to `target` and held (projection, then restarts). It may land on another
        assembly mode than the continuation would have; ConvergenceError (`what`) if it fails."""
        from kinematics.generic.assembly import AssemblyError, assemble

        values = self.robot.values_from_configuration(self.reference)
        values[self.actuated_dofs] = target
        try:
            a = assemble(self.robot, values, hold=self.spec.actuated, loop=self)
        except AssemblyError:
            raise ConvergenceError(what, total, err, tol) from None
        q, err, it = self.newton(a.q, tol)  # polish to the solver's tolerance
        if err > tol:
            raise ConvergenceError(what, total + it, err, tol)
        return self._solution(q, err, total + it)._replace(held=True)

    def _predict(self, q: np.ndarray, da: np.ndarray) -> tuple[np.ndarray, float] | None:
        """First-order step of every joint for an actuated change `da` along the loop manifold,
        or None when the passive joints would move more than MAX_PASSIVE_STEP (near a
        singularity the tangent blows up; a smaller step keeps to the branch)."""
        _, K = self.residual(q)
        dvp = -np.linalg.lstsq(K[:, self.passive_v], K[:, self.actuated_v] @ da, rcond=None)[0]
        moved = float(np.max(np.abs(dvp))) if dvp.size else 0.0
        if moved > MAX_PASSIVE_STEP:
            return None
        v = np.zeros(self.model.nv)
        v[self.actuated_v] = da
        v[self.passive_v] = dvp
        return pin.integrate(self.model, q, v), moved

    def _solution(self, q: np.ndarray, err: float, iterations: int) -> LoopSolution:
        # Revolute angles are periodic: report them within pi of the middle of their range.
        values = self.robot.values_from_configuration(q)
        for i, d in enumerate(self.robot.dofs):
            if d.kind == "revolute" and np.isfinite(d.lower) and np.isfinite(d.upper):
                centre = 0.5 * (d.lower + d.upper)
                values[i] = (values[i] - centre + np.pi) % (2 * np.pi) + centre - np.pi
        q = self.robot.configuration(values)
        pin.framesForwardKinematics(self.model, self.data, q)
        pose = pin.SE3(self.data.oMf[self.ee])
        return LoopSolution(q, values, pose, err, iterations)

    # -- velocities ------------------------------------------------------------------------------
    def passive_null(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(K_p, K_a, N) at q: the loop Jacobian's passive and actuated columns and an orthonormal
        basis N of null(K_p), the passive motions the loops allow with the actuators locked
        (singular values <= RANK_RTOL x the largest count as zero). Runs the kinematics at q."""
        _, K = self.residual(q)
        Kp, Ka = K[:, self.passive_v], K[:, self.actuated_v]
        if Kp.size == 0:
            return Kp, Ka, np.eye(Kp.shape[1])
        _, s, Vt = np.linalg.svd(Kp)  # full Vt: rows beyond len(s) span null(K_p) when K_p is wide
        rank = int(np.sum(s > RANK_RTOL * s[0])) if s.size and s[0] > 0 else 0
        return Kp, Ka, Vt[rank:].T

    def constrained_jacobian(self, q: np.ndarray, frame: str | None = None,
                             rows: Sequence[int] | None = None) -> np.ndarray:
        """len(rows) x n_actuated map from actuated joint rates to rows of a frame's twist [v; w]
        (world-aligned) at a closed configuration q (default: the end effector, all six rows).

        With N a basis of null(K_p) (passive motions the loops allow with the actuators locked),
        the rows are determined by the actuators iff J_p N = 0 on them. A passive freedom that
        does not move them (a coupler spinning about its own axis between two spherical joints)
        is harmless; the twist is then the same for every passive rate that closes the loops, and
        the minimum-norm one, -K_p^+ K_a, is used.

        Raises:
            SingularConfigurationError: J_p N != 0 on these rows (they can move with the actuators
                locked: a type II singularity, or a frame the actuators never hold).
            UnknownFrameError: no such frame.
        """
        fid = self.ee if frame is None else self.robot.frame_id(frame)
        sel = list(range(6)) if rows is None else list(rows)
        Kp, Ka, N = self.passive_null(q)
        J = matrix(pin.getFrameJacobian(self.model, self.data, fid, pin.LOCAL_WORLD_ALIGNED), self.model.nv)
        Jp = J[:, self.passive_v]
        ratio = free_ratio(Jp[sel], N)
        if ratio > FREE_RTOL:
            raise SingularConfigurationError(
                "constrained Jacobian", f"frame {self.model.frames[fid].name!r} can move with the actuators locked "
                f"(type II singularity: |J_p N| / |J_p| = {ratio:.2e}, {N.shape[1]} passive freedom(s) with the "
                "actuators locked)")
        dvp = -np.linalg.pinv(Kp, rcond=RANK_RTOL) @ Ka if Kp.size else np.zeros((0, Ka.shape[1]))
        return (J[:, self.actuated_v] + Jp @ dvp)[sel]


def free_ratio(Jp: np.ndarray, N: np.ndarray) -> float:
    """|J_p N| / |J_p| (spectral norms): how much the passive motions N left with the actuators
    locked move the rows J_p (0 where there are none)."""
    if N.shape[1] == 0 or Jp.size == 0:
        return 0.0
    scale = float(np.linalg.norm(Jp, 2))
    return float(np.linalg.norm(Jp @ N, 2)) / scale if scale > 0 else 0.0
