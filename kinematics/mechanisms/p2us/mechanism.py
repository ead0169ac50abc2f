"""The 3-[P2(US)] as a `Mechanism`: its closed forms and the compiled scan kernel behind the
common interface (branches: the 8 working modes; limits: every limit, or the strokes only)."""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import Any, ClassVar

import numpy as np

from kinematics.mechanisms.base import UNION, MarginFn, SingularFields
from kinematics.mechanisms.p2us import closed_form as cf
from kinematics.mechanisms.p2us.scan import bounding_box, check_limits, scan
from kinematics.mechanisms.three_limb.margin import ThreeLimbMargin
from kinematics.mechanisms.three_limb.mechanism import ThreeLimbMechanism

MODE_LEGEND = ("working mode: one sign per limb (limbs 1, 2, 3); '+' takes the IK root q = A + sqrt(A^2 - G) "
               "(carriage farther down its rail), '-' the root q = A - sqrt(A^2 - G); 'union': any mode")


def p2us_margin(params: cf.P2USParams, modes: Sequence[str] = cf.MODES, limits: str = "all") -> ThreeLimbMargin:
    """points (N, 3) -> (N, len(modes) + 1) margins [m]: each mode (the scan kernel's smallest
    constraint slack, `kinematics.mechanisms.p2us.scan`), then their union (the maximum); the
    returned object also carries the exact columns, `exact.ExactColumns`)."""
    from kinematics.mechanisms.p2us.exact import ExactColumns

    for m in modes:
        cf.mode_index(m)
    check_limits(limits)
    cols = [cf.MODES.index(m) for m in dict.fromkeys(modes)]
    return ThreeLimbMargin(params, cols, lambda points: scan(params, points, limits).margin,
                           ExactColumns(params, np.array(cols), limits))


class P2US(ThreeLimbMechanism):
    """The 3-[P2(US)] translational parallel robot (paper B) of a given design.

    Attributes:
        params: the design, read from its URDF (`kinematics.mechanisms.p2us.urdf.read_params`).
    """

    family = "p2us"
    description = "3-[P2(US)] translational parallel robot (closed forms)"
    actuator_unit = "m"
    branch_legend = MODE_LEGEND
    closed_form: ClassVar[ModuleType] = cf
    iota_I_label = "iota_I = min |n.w|"

    @property
    def rod_length(self) -> float:
        return float(self.params.L)

    def parameter_sources(self, urdf_path: str) -> dict[str, str]:
        """Paper B's table for each parameter of a built-in design (`paper_b.SOURCES`)."""
        from kinematics.mechanisms.p2us.paper_b import parameter_sources

        return parameter_sources(self.name, urdf_path)

    def reference_results(self, urdf_path: str, limits: str, per_mode: dict[str, float],
                          union: float) -> dict[str, Any]:
        """Paper B's volume beside ours and the passive limits' share (`paper_b.reference_report`)."""
        from kinematics.mechanisms.p2us.paper_b import reference_report

        return reference_report(self.params, self.name, urdf_path, limits, per_mode, union)

    def reference_lines(self, results: dict[str, Any]) -> list[str]:
        from kinematics.mechanisms.p2us.paper_b import reference_lines

        return reference_lines(results)

    def paper_scan(self) -> dict[str, Any]:
        """Paper B's 8 x 8 x 8 actuator scan (`paper_scan.paper_scan`)."""
        from kinematics.mechanisms.p2us.paper_scan import paper_scan

        return paper_scan(self.params)

    def sweep_parameters(self) -> cf.P2USParams:
        return self.params

    def limb_reasons(self, limbs: cf.LimbSolutions) -> list[dict[str, Any]]:
        return [{"limb": i + 1, "reachable": bool(limbs.reach[i]),
                 "reason": None if limbs.reach[i] else (
                     f"limb {i + 1} cannot reach: its platform joint is {limbs.axis_distance[i]:.6g} m from the "
                     f"rail's axis, farther than the rod length L = {self.params.L:g} m")} for i in range(3)]

    def fk_reason(self, res: Any) -> str:
        return (f"no assembly: the three spheres of radius L = {self.params.L:g} m around the carriages do not "
                f"meet (the rods would need to be {float(res.gap):.6g} m longer)")

    def kernels(self) -> tuple[Any, ...]:
        import kinematics.mechanisms.p2us.scan as scan_module
        from kinematics.mechanisms.p2us import configurations, exact

        return (*scan_module.kernels(), *exact.kernels(), *configurations.kernels())

    def bounding_box(self, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        self.check_limits(limits)
        return bounding_box(self.params)

    def margin(self, branches: Sequence[str] | None = None, limits: str = "all") -> MarginFn:
        return p2us_margin(self.params, self.check_branches(branches), limits)

    def singular_fields(self, points: np.ndarray, limits: str = "all") -> SingularFields:
        s = scan(self.params, points, limits)
        return SingularFields(s.margin, s.disc, s.det)


__all__ = ["MODE_LEGEND", "P2US", "UNION", "p2us_margin"]
