"""Clavel's Delta as a `Mechanism`: its closed forms behind the common interface (branches: the 8
working modes; limits: every limit, or the actuator range only).

Margin of working mode m at platform position p [m]: the smallest, over the three limbs in the
root that m takes, of

* reach: min(l_b - near, far - l_b), the forearm's slack to the nearest and farthest points of
  the elbow circle (`closed_form.limb_ik`) [m]: > 0 iff the limb reaches;
* actuator: l_a min(theta - theta_min, theta_max - theta) (the elbow's travel to the limit) [m];
* ball joints ("all" limits): l_b (cone - angle) at the elbow and at the platform (the rod tip's
  travel to the cone) [m].

Where a limb cannot reach, only its (negative) reach slack counts. The terms are continuous in
p (the two IK roots merge where the reach slack is 0), so the margin is too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from types import ModuleType
from typing import Any, ClassVar

import numpy as np

from kinematics.mechanisms.base import MarginFn, SingularFields
from kinematics.mechanisms.delta import closed_form as cf
from kinematics.mechanisms.delta.scan import scan
from kinematics.mechanisms.three_limb.mechanism import ThreeLimbMechanism
from kinematics.mechanisms.three_limb.modes import LIMITS as LIMITS
from kinematics.mechanisms.three_limb.modes import check_limits

MODE_LEGEND = ("working mode: one sign per limb (limbs 1, 2, 3); '+' turns the upper arm from the line actuator "
               "axis -> platform joint towards larger theta, '-' the other way ('---': the usual elbows-out "
               "Delta); 'union': any mode")


def limb_margins(params: cf.DeltaParams, points: np.ndarray, limits: str = "all") -> np.ndarray:
    """(N, 3, 2) per limb and root: the smallest slack [m] (see the module docstring)."""
    passive = check_limits(limits)
    limbs = cf.limb_ik(params, np.asarray(points, dtype=float))
    reach = np.minimum(params.lb - limbs.near, limbs.far - params.lb)  # (N, 3)
    lo, hi = params.theta_limits
    with np.errstate(invalid="ignore"):
        slack = params.la * np.minimum(limbs.q - lo, hi - limbs.q)  # (N, 3, 2)
        if passive:
            ce, cp = cf.cone_angles(params, limbs.q, limbs.n)
            slack = np.minimum(slack, params.lb * (params.cone - np.maximum(ce, cp)))
        out = np.minimum(reach[..., None], slack)
    return np.where(limbs.reach[..., None] & np.isfinite(out), out, np.minimum(reach, 0.0)[..., None])


class Delta(ThreeLimbMechanism):
    """Clavel's 3-RUU Delta robot of a given design."""

    family = "delta"
    description = "3-RUU Delta robot (closed forms)"
    actuator_unit = "rad"
    branch_legend = MODE_LEGEND
    closed_form: ClassVar[ModuleType] = cf
    iota_I_label = "iota_I = min |n.b|"

    @property
    def rod_length(self) -> float:
        return float(self.params.lb)

    def bounding_box(self, limits: str = "all") -> tuple[np.ndarray, np.ndarray]:
        """A box [m] that contains the workspace under `limits` (proved, not sampled).

        Limb i puts the platform centre at p = (R - r) e_i + l_a d_i(theta) + l_b n, with theta in
        the actuator range and n the unit forearm direction; with every limit, n also lies in the
        platform ball joint's cone (angle(n, -s_P,i) <= cone). For each world direction +/-u the
        support max u.p of that superset is the arc's max of u.d_i(theta) over the range (its ends
        and its stationary angle) plus l_b cos(max(0, angle(u, -s_P,i) - cone)) (l_b for the
        actuators only: any n). The box is the intersection of the three limbs' boxes; the elbow
        cones, which couple n to theta, are left out, so it is a superset.
        """
        passive = check_limits(limits)
        P = self.params
        lo_t, hi_t = P.theta_limits
        lo = np.full(3, -np.inf)
        hi = np.full(3, np.inf)
        for i in range(3):
            axis = -P.platform_sockets[i]
            for k in range(3):
                for sign in (1.0, -1.0):
                    u = np.zeros(3)
                    u[k] = sign
                    a, b = float(u @ P.e[i]), float(u[2])  # u.d(theta) = a cos(theta) - b sin(theta)
                    beta = math.atan2(b, a)
                    thetas = [lo_t, hi_t, *(t for t in (-beta + 2 * math.pi * j for j in range(-2, 3))
                                            if lo_t <= t <= hi_t)]
                    arc = max(a * math.cos(t) - b * math.sin(t) for t in thetas)
                    rod = math.cos(max(0.0, math.acos(max(-1.0, min(1.0, float(u @ axis)))) - P.cone)) \
                        if passive else 1.0
                    support = (P.R - P.r) * float(u @ P.e[i]) + P.la * arc + P.lb * rod
                    if sign > 0:
                        hi[k] = min(hi[k], support)
                    else:
                        lo[k] = max(lo[k], -support)
        return lo, hi

    def margin(self, branches: Sequence[str] | None = None, limits: str = "all") -> MarginFn:
        from kinematics.mechanisms.delta.exact import delta_margin

        cols = [cf.MODES.index(b) for b in self.check_branches(branches)]
        self.check_limits(limits)
        return delta_margin(self.params, cols, limits == "all")

    def singular_fields(self, points: np.ndarray, limits: str = "all") -> SingularFields:
        """Type I of limb i where its IK discriminant rho^2 - K^2 [m^2] changes sign; type II of
        mode m where det[n_1; n_2; n_3] of that mode's forearm directions does."""
        s = scan(self.params, np.asarray(points, dtype=float), check_limits(limits))
        return SingularFields(s.margin, s.disc, s.det)

    def kernels(self) -> tuple[Any, ...]:
        from kinematics.mechanisms.delta import exact, scan

        return (*scan.kernels(), *exact.kernels())
