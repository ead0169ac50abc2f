"""Single-pose reports (`Mechanism.pose_ik`, `pose_fk`, `pose_jacobians`) of the three-limb
translational parallel robots (the 3-[P2(US)], the Delta) from their closed forms: both families
give IK results over the 8 working modes with per-limb rod directions, FK results over the two
assembly modes, and Jacobians with the same fields."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from kinematics.mechanisms.base import PoseFK, PoseIK, PoseJacobians
from kinematics.mechanisms.translational import MODES

Violations = Callable[[np.ndarray, np.ndarray], list[str]]
"""(q (3,), unit rod directions n (3, 3)) -> the limits that pose breaks, in words."""


def pose_ik(res: Any, violations: Violations, limbs: list[dict[str, Any]]) -> PoseIK:
    """From a family's IK result at one point (q (8, 3), reachable, within_limits, limbs.n
    (3, 2, 3) per limb and root): each assembling mode's violations, with that mode's rods."""
    found: list[tuple[str, ...]] = []
    for m, mode in enumerate(MODES):
        if not res.reachable[m]:
            found.append(())
            continue
        roots = [0 if c == "+" else 1 for c in mode]
        found.append(tuple(violations(res.q[m], res.limbs.n[np.arange(3), roots])))
    return PoseIK(res.q, np.asarray(res.reachable), np.asarray(res.within_limits), tuple(found), limbs)


def pose_fk(res: Any, q: np.ndarray, rods: Callable[[np.ndarray], np.ndarray], rod_length: float,
            violations: Violations, reason: Callable[[Any], str]) -> PoseFK:
    """From a family's FK result at one actuator vector (p (2, 3), exists, gap): each assembly
    mode's violations, its unit rod directions rods(p) / rod_length; `reason(res)` when none exists."""
    exists = bool(res.exists)
    found = tuple(tuple(violations(q, rods(res.p[k]) / rod_length)) for k in range(len(res.p))) if exists else ()
    return PoseFK(res.p, exists, found, None if exists else reason(res))


def pose_jacobians(jac: Any) -> PoseJacobians:
    """From a family's Jacobians at one pose (Jx, Jq, J, iota_I, iota_II)."""
    return PoseJacobians(jac.Jx, jac.Jq, jac.J, jac.iota_I, jac.iota_II)
