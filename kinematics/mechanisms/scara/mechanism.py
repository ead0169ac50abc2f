"""The planar 2R arm (paper A's SCARA) as a `Mechanism`: closed forms behind the common interface
(task space: the plane (x, y); branches: the two elbows).

Margin of an elbow at (x, y) [m]: the smaller of the reach slacks (l1 + l2 - r, r - |l1 - l2|)
[m] and the joint-limit slacks [rad] times l1 + l2 (~ the tip's travel to the limit) [m], the
joint angles computed with r clamped into the annulus (continuous, and exactly the IK inside it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from kinematics.inputs import task_points
from kinematics.mechanisms.base import Assemblies, BranchIK, MarginFn, Mechanism, PoseIK, Velocity
from kinematics.mechanisms.scara import closed_form as cf

ELBOW_LEGEND = "elbow: 'up' takes theta2 < 0, 'down' theta2 > 0; 'union': either"


def scara_margin(sp: cf.ScaraParams, elbows: Sequence[str] = cf.ELBOWS) -> MarginFn:
    """points (N, 2) -> (N, len(elbows) + 1) margins [m]: each elbow, then their union (the module
    docstring)."""
    from kinematics.errors import UnknownModeError

    for e in elbows:
        if e not in cf.ELBOWS:
            raise UnknownModeError(e, cf.ELBOWS)
    if not elbows:
        raise UnknownModeError("", cf.ELBOWS)
    elbows = tuple(dict.fromkeys(elbows))
    inner, outer = sp.reach
    lo, hi = np.asarray(sp.lower), np.asarray(sp.upper)

    def margin(points: np.ndarray) -> np.ndarray:
        points = task_points(points, 2)
        x, y = points[:, 0], points[:, 1]
        r = np.hypot(x, y)
        reach = np.minimum(outer - r, r - inner)
        rc = np.clip(r, inner, outer)
        c2 = np.clip((rc * rc - sp.l1**2 - sp.l2**2) / (2 * sp.l1 * sp.l2), -1.0, 1.0)
        phi = np.arctan2(y, x)
        cols = []
        for elbow in elbows:
            t2 = (-1.0 if elbow == "up" else 1.0) * np.arccos(c2)
            t1 = phi - np.arctan2(sp.l2 * np.sin(t2), sp.l1 + sp.l2 * np.cos(t2))
            t1 = (t1 + math.pi) % (2 * math.pi) - math.pi
            q = np.stack([t1, t2], axis=-1)
            joint = np.minimum(q - lo, hi - q).min(axis=-1) * outer
            cols.append(np.minimum(reach, joint))
        m = np.stack(cols, axis=1)
        return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

    return margin


class Scara(Mechanism):
    """A planar 2R arm read from its URDF (`ScaraParams.from_robot`)."""

    family = "scara"
    description = "planar 2R arm (closed forms)"
    task_dim = 2
    task_axes = ("x", "y")
    branch_kind = "elbow"
    branches = cf.ELBOWS
    branch_legend = ELBOW_LEGEND
    assembly_modes = ("tool",)

    def __init__(self, params: cf.ScaraParams, name: str = "scara") -> None:
        self.params = params
        self.name = name

    def parameters(self) -> dict[str, Any]:
        p = self.params
        return {"l1": p.l1, "l2": p.l2, "lower": list(p.lower), "upper": list(p.upper)}

    def joint_singularities(self, angle_step: float | None = None) -> dict[str, Any]:
        """det J = l1 l2 sin(theta2) = 0 over the joint grid (`joint_space.singular_set`)."""
        from kinematics.mechanisms.scara.joint_space import singular_set

        return singular_set(self.params) if angle_step is None else singular_set(self.params, angle_step)

    def design_parameters(self) -> dict[str, Any]:
        """The link lengths (the joint limits are the URDF's)."""
        return {"l1": self.params.l1, "l2": self.params.l2}

    def bounding_box(self, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        self.check_limits(limits)
        outer = self.params.reach[1]
        return np.full(2, -outer), np.full(2, outer) + 1e-9  # the outer circle's extreme points inside

    def margin(self, branches: Sequence[str] | None = None, limits: str = "all") -> MarginFn:
        self.check_limits(limits)
        return scara_margin(self.params, self.check_branches(branches))

    def ik(self, points: np.ndarray, limits: str = "all") -> BranchIK:
        self.check_limits(limits)
        res = cf.ik(self.params, points)
        reach = np.broadcast_to(res.reachable[..., None], res.within_limits.shape)
        return BranchIK(res.q, np.asarray(reach), res.within_limits)

    def fk(self, q: np.ndarray) -> Assemblies:
        p = cf.fk(self.params, q)[..., None, :]
        return Assemblies(p, np.ones(p.shape[:-1], dtype=bool), ("tool",))

    def velocity(self, points: np.ndarray, q: np.ndarray) -> Velocity:
        """J = d(x, y)/d(theta1, theta2) [m/rad]; iota_I = |sin theta2| = |det J| / (l1 l2)."""
        J = cf.jacobian(self.params, q)
        iota = np.abs(np.sin(np.asarray(q, dtype=float)[..., 1]))
        bad = iota <= 0.0
        with np.errstate(invalid="ignore", divide="ignore"):
            Ji = np.linalg.inv(np.where(bad[..., None, None], np.eye(2), J))
        return Velocity(J, np.where(bad[..., None, None], np.nan, Ji), iota, np.ones_like(iota))

    def pose_ik(self, point: np.ndarray) -> PoseIK:
        """Both elbows at `point` (x, y) [m] (`closed_form.solve_ik`), each with the joint limits it
        breaks; the chain is the one limb, unreachable outside the annulus |l1 - l2| <= r <= l1 + l2."""
        res = cf.ik(self.params, np.asarray(point, dtype=float))
        answer = cf.solve_ik(self.params, point)
        found = {s.elbow: s.violations for s in answer.solutions}
        reachable = bool(res.reachable)
        reason = None if reachable else answer.reason
        return PoseIK(res.q, np.full(len(cf.ELBOWS), reachable), np.asarray(res.within_limits),
                      tuple(found.get(e, ()) for e in cf.ELBOWS), [{"limb": 1, "reachable": reachable, "reason": reason}])
