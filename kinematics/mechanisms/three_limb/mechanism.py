"""What the three-limb families' `Mechanism`s do alike: forward their design to the family's
closed forms (IK in the 8 working modes, FK in the two assembly modes, the velocity matrices,
and the single-pose reports of `kinematics ik|fk|jacobian`) and to its URDF module (reference
pose, joint values of the URDF tree)."""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any, ClassVar

import numpy as np

from kinematics.mechanisms.base import (
    Assemblies,
    BranchIK,
    Mechanism,
    PoseFK,
    PoseIK,
    PoseJacobians,
    Velocity,
    parallel_forward,
)
from kinematics.mechanisms.three_limb.closed_form import ASSEMBLY_MODES, MODES
from kinematics.mechanisms.three_limb.modes import LIMITS, actuators, check_limits, one, points


class ThreeLimbMechanism(Mechanism):
    """A three-limb translational parallel robot of a given design (branches: the 8 working
    modes; limits: `limit_sets`, "all" checking the passive joints too).

    Subclasses name their `closed_form` module (with `ik`, `fk`, `jacobians`, `rod_vectors`,
    `violations`, and for the default reasons `limb_reasons`, `fk_reason`), their `rod_length` and
    `iota_I_label`; the `urdf` module beside it (with `reference_pose`, `joint_values_at`) is
    imported on first use.

    Attributes:
        params: the design (the family's parameter dataclass), read from its URDF.
    """

    closed_loop = True
    branch_kind = "working mode"
    branches = MODES
    assembly_modes = ASSEMBLY_MODES
    limit_sets = LIMITS
    limits_in_design = True  # one stroke, theta range, cone... for the three limbs, from the URDF
    closed_form: ClassVar[ModuleType]

    def __init__(self, params: Any, name: str | None = None) -> None:
        self.params = params
        self.name = name or self.family

    def parameters(self) -> dict[str, Any]:
        return self.params.as_dict()

    def design_parameters(self) -> dict[str, Any]:
        return self.params.as_dict()

    @property
    def rod_length(self) -> float:
        """The rods' (forearms') length [m]: a rod's unit direction is its vector over it."""
        raise NotImplementedError(f"{type(self).__name__} names its rod length")

    def passive_limits(self, limits: str) -> bool:
        """Whether `limits` (one of `limit_sets`, else UnknownChoiceError) checks the passive joints."""
        return check_limits(limits)

    def ik(self, points: np.ndarray, limits: str = "all") -> BranchIK:
        res = self.closed_form.ik(self.params, points, limits=self.passive_limits(limits))
        return BranchIK(res.q, np.asarray(res.reachable), res.within_limits)

    def fk(self, q: np.ndarray) -> Assemblies:
        res = self.closed_form.fk(self.params, q)
        return Assemblies(res.p, np.isfinite(res.p).all(axis=-1), ASSEMBLY_MODES)

    def velocity(self, points: np.ndarray, q: np.ndarray) -> Velocity:
        jac = self.closed_form.jacobians(self.params, points, q)
        return Velocity(parallel_forward(jac.Jx, jac.Jq, jac.iota_II), jac.J, jac.iota_I, jac.iota_II)

    @property
    def actuator_word(self) -> str:
        """What the actuator values are, for messages: "angles" (revolute) or "values"."""
        return "angles" if self.actuator_unit == "rad" else "values"

    def urdf_module(self) -> Any:
        """The family's URDF module (`<family package>.urdf`), imported on first use."""
        return importlib.import_module(f"{self.closed_form.__package__}.urdf")

    def reference_pose(self) -> tuple[np.ndarray, str]:
        pose: tuple[np.ndarray, str] = self.urdf_module().reference_pose(self.params)
        return pose

    def joint_values(self, point: np.ndarray, branch: str) -> dict[str, float]:
        point = one(points(point), "position")
        values: dict[str, float] = self.urdf_module().joint_values_at(self.params, point,
                                                                       self.check_branches([branch])[0])
        return values

    # -- single-pose reports -------------------------------------------------------------------
    def limb_reasons(self, limbs: Any) -> list[dict[str, Any]]:
        """Per-limb reachability at one point, with the reason when a limb cannot reach."""
        reasons: list[dict[str, Any]] = self.closed_form.limb_reasons(self.params, limbs)
        return reasons

    def fk_reason(self, res: Any) -> str:
        """Why a single FK query (`closed_form.fk` at one actuator vector) has no assembly."""
        reason: str = self.closed_form.fk_reason(self.params, res)
        return reason

    def pose_ik(self, point: np.ndarray) -> PoseIK:
        """Every working mode at `point`, with the limits each assembling mode breaks (its rods
        from the IK's per-limb roots)."""
        cf, P = self.closed_form, self.params
        res = cf.ik(P, one(points(point), "position"))
        found: list[tuple[str, ...]] = []
        for m, mode in enumerate(MODES):
            roots = [0 if c == "+" else 1 for c in mode]
            found.append(tuple(cf.violations(P, res.q[m], res.limbs.n[np.arange(3), roots]))
                         if res.reachable[m] else ())
        return PoseIK(res.q, np.asarray(res.reachable), np.asarray(res.within_limits), tuple(found),
                      self.limb_reasons(res.limbs))

    def pose_fk(self, q: np.ndarray) -> PoseFK:
        """Both assembly modes at `q`, with the limits each breaks (its rods from the platform
        position), or why none exists."""
        cf, P = self.closed_form, self.params
        q = one(actuators(q, self.actuator_word), "q")
        res = cf.fk(P, q)
        if not res.exists:
            return PoseFK(res.p, False, (), self.fk_reason(res))
        found = tuple(tuple(cf.violations(P, q, cf.rod_vectors(P, p, q) / self.rod_length)) for p in res.p)
        return PoseFK(res.p, True, found, None)

    def pose_jacobians(self, point: np.ndarray, q: np.ndarray) -> PoseJacobians:
        jac = self.closed_form.jacobians(self.params, one(points(point), "position"), one(actuators(q, self.actuator_word), "q"))
        return PoseJacobians(jac.Jx, jac.Jq, jac.J, jac.iota_I, jac.iota_II)
