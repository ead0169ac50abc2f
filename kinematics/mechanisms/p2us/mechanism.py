"""The 3-[P2(US)] as a `Mechanism`: its closed forms and the compiled scan kernel behind the
common interface (branches: the 8 working modes; limits: every limit, or the strokes only)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from kinematics.mechanisms.base import (
    UNION,
    Assemblies,
    BranchIK,
    MarginFn,
    Mechanism,
    PoseFK,
    PoseIK,
    PoseJacobians,
    SingularFields,
    Velocity,
    parallel_forward,
)
from kinematics.mechanisms.p2us import closed_form as cf
from kinematics.mechanisms.p2us.scan import LIMITS, bounding_box, check_limits, scan
from kinematics.mechanisms.pose_reports import pose_fk, pose_ik, pose_jacobians

MODE_LEGEND = ("working mode: one sign per limb (limbs 1, 2, 3); '+' takes the IK root q = A + sqrt(A^2 - G) "
               "(carriage farther down its rail), '-' the root q = A - sqrt(A^2 - G); 'union': any mode")


def p2us_margin(params: cf.P2USParams, modes: Sequence[str] = cf.MODES, limits: str = "all") -> P2USMargin:
    """points (N, 3) -> (N, len(modes) + 1) margins [m]: each mode (the scan kernel's smallest
    constraint slack, `kinematics.mechanisms.p2us.scan`), then their union (the maximum); the
    returned object also carries the exact columns (`P2USMargin`)."""
    for m in modes:
        cf.mode_index(m)
    check_limits(limits)
    return P2USMargin(params, [cf.MODES.index(m) for m in dict.fromkeys(modes)], limits)


class P2USMargin:
    """The 3-[P2(US)] margin as `p2us_margin` returns it: callable on points, and with
    `exact_columns` (`exact.ExactColumns`), which `column_volume` uses instead of sampling."""

    def __init__(self, params: cf.P2USParams, cols: list[int], limits: str) -> None:
        from kinematics.mechanisms.p2us.exact import ExactColumns

        self.params, self.cols, self.limits = params, cols, limits
        self.exact_columns = ExactColumns(params, np.array(cols), limits)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        m = scan(self.params, points, self.limits).margin[:, self.cols]
        return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

    def sampled(self) -> MarginFn:
        """The same margin without exact columns (the engine then samples every column)."""
        def margin(points: np.ndarray) -> np.ndarray:
            return self(points)

        return margin


class P2US(Mechanism):
    """The 3-[P2(US)] translational parallel robot (paper B) of a given design.

    Attributes:
        params: the design, read from its URDF (`kinematics.mechanisms.p2us.urdf.read_params`).
    """

    family = "p2us"
    closed_loop = True
    description = "3-[P2(US)] translational parallel robot (closed forms)"
    actuator_unit = "m"
    branch_kind = "working mode"
    branches = cf.MODES
    branch_legend = MODE_LEGEND
    limit_sets = LIMITS
    assembly_modes = cf.ASSEMBLY_MODES
    iota_I_label = "iota_I = min |n.w|"

    def __init__(self, params: cf.P2USParams, name: str = "p2us") -> None:
        self.params = params
        self.name = name

    def parameters(self) -> dict[str, Any]:
        return self.params.as_dict()

    def design_parameters(self) -> dict[str, Any]:
        return self.params.as_dict()

    def parameter_sources(self, urdf_path: str) -> dict[str, str]:
        """Paper B's table for each parameter of a built-in design (`paper_b.SOURCES`)."""
        from kinematics.mechanisms.p2us.paper_b import parameter_sources

        return parameter_sources(self.name, urdf_path)

    def limb_reasons(self, limbs: cf.LimbSolutions) -> list[dict[str, Any]]:
        """Per-limb reachability at one point, with the reason when a limb cannot reach."""
        return [{"limb": i + 1, "reachable": bool(limbs.reach[i]),
                 "reason": None if limbs.reach[i] else (
                     f"limb {i + 1} cannot reach: its platform joint is {limbs.axis_distance[i]:.6g} m from the "
                     f"rail's axis, farther than the rod length L = {self.params.L:g} m")} for i in range(3)]

    def fk_reason(self, res: Any) -> str:
        """Why a single FK query has no assembly."""
        return (f"no assembly: the three spheres of radius L = {self.params.L:g} m around the carriages do not "
                f"meet (the rods would need to be {float(res.gap):.6g} m longer)")

    def pose_ik(self, point: np.ndarray) -> PoseIK:
        res = cf.ik(self.params, point)
        return pose_ik(res, lambda q, n: cf.violations(self.params, q, n), self.limb_reasons(res.limbs))

    def pose_fk(self, q: np.ndarray) -> PoseFK:
        return pose_fk(cf.fk(self.params, q), q, lambda p: cf.rod_vectors(self.params, p, q), self.params.L,
                       lambda qq, n: cf.violations(self.params, qq, n), self.fk_reason)

    def pose_jacobians(self, point: np.ndarray, q: np.ndarray) -> PoseJacobians:
        return pose_jacobians(cf.jacobians(self.params, point, q))

    def kernels(self) -> tuple[Any, ...]:
        import kinematics.mechanisms.p2us.scan as scan_module
        from kinematics.mechanisms.p2us import exact

        return (*scan_module.kernels(), *exact.kernels())

    def bounding_box(self, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        self.check_limits(limits)
        return bounding_box(self.params)

    def margin(self, branches: Sequence[str] | None = None, limits: str = "all") -> MarginFn:
        return p2us_margin(self.params, self.check_branches(branches), limits)

    def ik(self, points: np.ndarray, limits: str = "all") -> BranchIK:
        res = cf.ik(self.params, points, limits=check_limits(limits))
        return BranchIK(res.q, np.asarray(res.reachable), res.within_limits)

    def fk(self, q: np.ndarray) -> Assemblies:
        res = cf.fk(self.params, q)
        exists = np.isfinite(res.p).all(axis=-1)
        return Assemblies(res.p, exists, cf.ASSEMBLY_MODES)

    def velocity(self, points: np.ndarray, q: np.ndarray) -> Velocity:
        jac = cf.jacobians(self.params, points, q)
        return Velocity(parallel_forward(jac.Jx, jac.Jq, jac.iota_II), jac.J, jac.iota_I, jac.iota_II)

    def reference_pose(self) -> tuple[np.ndarray, str]:
        from kinematics.mechanisms.p2us.urdf import reference_pose

        return reference_pose(self.params)

    def joint_values(self, point: np.ndarray, branch: str) -> dict[str, float]:
        from kinematics.mechanisms.p2us.urdf import joint_values_at

        return joint_values_at(self.params, point, self.check_branches([branch])[0])

    def singular_fields(self, points: np.ndarray, limits: str = "all") -> SingularFields:
        s = scan(self.params, points, limits)
        return SingularFields(s.margin, s.disc, s.det)


__all__ = ["MODE_LEGEND", "P2US", "UNION", "P2USMargin", "p2us_margin"]
