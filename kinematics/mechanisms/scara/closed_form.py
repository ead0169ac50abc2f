"""Closed forms of the planar 2R arm (the SCARA's first two joints), vectorised.

Conventions (those of `urdf/scara.urdf`): both axes along +z, angles measured counter-clockwise,
zero with both links along +x. With c1 = cos(theta1), c12 = cos(theta1 + theta2), ...

    x = l1 c1 + l2 c12,  y = l1 s1 + l2 s12                                         [m]
    J = [[-l1 s1 - l2 s12, -l2 s12], [l1 c1 + l2 c12, l2 c12]],  det J = l1 l2 s2   [m^2]

Singular where theta2 = 0 (stretched, on the outer boundary r = l1 + l2); theta2 = +/-pi (folded)
is outside the SCARA's joint-2 range. Elbow naming: "up" is theta2 <= 0, "down" is
theta2 >= 0 (for a target on +x, theta2 > 0 puts the elbow below the base-tip line).

Every function takes arrays of any leading shape S: q has shape S + (2,), positions S + (2,).
l1, l2 and the limits come from the URDF through `ScaraParams.from_robot`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.errors import InvalidInputError, UnsupportedRobotError
from kinematics.generic.manipulability import SINGULAR_RTOL, Ellipses
from kinematics.inputs import finite_vectors
from kinematics.model.robot import Robot

ELBOWS = ("up", "down")
"""IK branch labels, in the order of the branch axis of `ik` results."""

BOUNDARY_TOL = 1e-12
"""|cos theta2| may exceed 1 by this much (rounding on the workspace boundary) and still count."""

LIMIT_TOL = 1e-12
"""[rad] A joint angle this close beyond an end of its range counts as within it: the IK gives
back an angle the FK was given on an end to a few ulp (atan2's round-off, ~1e-16 rad), so fk then
ik keeps such a pose within the limits; 1e-12 leaves a factor 1e4."""


@dataclass(frozen=True)
class ScaraParams:
    """Link lengths [m] and joint limits [rad] of a planar 2R arm."""

    l1: float
    l2: float
    lower: tuple[float, float]
    upper: tuple[float, float]

    @classmethod
    def from_robot(cls, robot: Robot) -> ScaraParams:
        """Read l1, l2 and the limits from a loaded URDF model.

        The model must be two revolute joints about +z, joint 2 offset from joint 1 along
        link 1's x axis, and the tool frame offset from joint 2 along link 2's x axis, both
        lengths positive, both ranges given; anything else is a general serial arm.
        """
        model = robot.model
        kinds = [d.kind for d in robot.dofs]
        if kinds != ["revolute", "revolute"]:
            raise UnsupportedRobotError(robot.name, f"a planar 2R arm needs two revolute joints, found {kinds}")
        for jid in (1, 2):
            axis = _joint_axis(model, jid)
            if not np.allclose(axis, [0, 0, 1], atol=1e-12):
                raise UnsupportedRobotError(
                    robot.name, f"joint {model.names[jid]!r} axis is {axis.tolist()}, expected [0, 0, 1]"
                )
        p1 = model.jointPlacements[1]
        p2 = model.jointPlacements[2]
        tool = model.frames[robot.frame_id()]
        if tool.parentJoint != 2:
            raise UnsupportedRobotError(robot.name, f"tool frame {tool.name!r} is not on joint 2's link")
        offsets = {"joint 1 (from base)": p1, "joint 2 (from joint 1)": p2, "tool (from joint 2)": tool.placement}
        for what, M in offsets.items():
            if not np.allclose(M.rotation, np.eye(3), atol=1e-12) or abs(M.translation[1]) > 1e-12:
                raise UnsupportedRobotError(robot.name, f"{what} must be a pure offset along x (and z)")
        if abs(p1.translation[0]) > 1e-12:
            raise UnsupportedRobotError(robot.name, "joint 1 must sit on the base's z axis")
        l1, l2 = float(p2.translation[0]), float(tool.placement.translation[0])
        if not (l1 > 0 and l2 > 0):
            raise UnsupportedRobotError(robot.name, f"link lengths l1 = {l1:g} m, l2 = {l2:g} m: the closed form "
                                                    "needs both positive")
        if not all(d.range_given for d in robot.dofs):
            raise UnsupportedRobotError(robot.name, "the closed form needs both joints' ranges")
        lo, hi = robot.lower, robot.upper
        return cls(
            l1=l1,
            l2=l2,
            lower=(float(lo[0]), float(lo[1])),
            upper=(float(hi[0]), float(hi[1])),
        )

    @property
    def reach(self) -> tuple[float, float]:
        """Inner and outer workspace radii |l1 - l2|, l1 + l2 [m] (joint limits ignored)."""
        return abs(self.l1 - self.l2), self.l1 + self.l2


def _joint_axis(model: pin.Model, jid: int) -> np.ndarray:
    """World direction of joint `jid`'s rotation axis at the neutral configuration."""
    d = model.createData()
    pin.computeJointJacobians(model, d, pin.neutral(model))
    return np.asarray(pin.getJointJacobian(model, d, jid, pin.LOCAL_WORLD_ALIGNED)[3:, 0])


def _angles(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    q = finite_vectors(q, 2, "q")
    return q[..., 0], q[..., 1]


def fk(p: ScaraParams, q: np.ndarray) -> np.ndarray:
    """Tool position (x, y) [m], shape S + (2,)."""
    t1, t2 = _angles(q)
    t12 = t1 + t2
    return np.stack([p.l1 * np.cos(t1) + p.l2 * np.cos(t12), p.l1 * np.sin(t1) + p.l2 * np.sin(t12)], axis=-1)


def jacobian(p: ScaraParams, q: np.ndarray) -> np.ndarray:
    """Task Jacobian d(x, y)/d(theta1, theta2) [m/rad], shape S + (2, 2)."""
    t1, t2 = _angles(q)
    s1, c1 = np.sin(t1), np.cos(t1)
    s12, c12 = np.sin(t1 + t2), np.cos(t1 + t2)
    row0 = np.stack([-p.l1 * s1 - p.l2 * s12, -p.l2 * s12], axis=-1)
    row1 = np.stack([p.l1 * c1 + p.l2 * c12, p.l2 * c12], axis=-1)
    return np.stack([row0, row1], axis=-2)


def det_jacobian(p: ScaraParams, q: np.ndarray) -> np.ndarray:
    """det J = l1 l2 sin(theta2) [m^2]."""
    _, t2 = _angles(q)
    return p.l1 * p.l2 * np.sin(t2)


def manipulability(p: ScaraParams, q: np.ndarray, rtol: float = SINGULAR_RTOL) -> Ellipses:
    """Manipulability ellipses at every configuration of `q` (closed form, no SVD).

    J(theta1, theta2) = R(theta1) J(0, theta2), so J J^T = R M(theta2) R^T: the radii depend on
    theta2 only and the directions turn rigidly with theta1. With J0 = J(0, theta2),
    M = [[a, b], [b, c]], a = 2 (l2 s2)^2, b = -l2 s2 (l1 + 2 l2 c2), c = (l1 + l2 c2)^2 + (l2 c2)^2:

        r_max^2 = (a + c)/2 + sqrt(((a - c)/2)^2 + b^2),   r_min = |l1 l2 s2| / r_max,
        major axis at angle theta1 + atan2(b, (a - c)/2) / 2.

    r_min uses det J = l1 l2 s2 directly, so it stays accurate up to the singularity.
    """
    t1, t2 = _angles(q)
    s2, c2 = np.sin(t2), np.cos(t2)
    det = (p.l1 * p.l2) * s2
    ls = p.l2 * s2
    lc = p.l2 * c2
    reach = p.l1 + lc
    a = 2.0 * ls * ls
    b = -ls * (reach + lc)
    c = reach * reach + lc * lc
    half_diff = 0.5 * (a - c)
    r_max = np.sqrt(0.5 * (a + c) + np.sqrt(half_diff * half_diff + b * b))
    with np.errstate(divide="ignore", invalid="ignore"):
        r_min = np.where(r_max > 0, np.abs(det) / r_max, 0.0)
        cond = np.where(r_min > 0, r_max / r_min, np.inf)
    psi = 0.5 * np.arctan2(b, half_diff) + t1
    major = _canonical_2d(np.cos(psi), np.sin(psi))
    minor = _canonical_2d(-major[..., 1], major[..., 0])
    return Ellipses(
        radii=np.stack([r_min, r_max], axis=-1),
        directions=np.stack([minor, major], axis=-2),
        yoshikawa=np.abs(det),
        condition_number=cond,
        singular=r_min <= rtol * r_max,
    )


def _canonical_2d(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Stack (x, y) with the sign that makes the larger-magnitude component positive (x on ties)."""
    sign = np.copysign(1.0, np.where(np.abs(x) >= np.abs(y), x, y))
    return np.stack([x * sign, y * sign], axis=-1)


class ScaraIK(NamedTuple):
    """Vectorised IK result for positions of shape S + (2,).

    Attributes:
        q: S + (2, 2): q[..., k, :] is the solution of elbow ELBOWS[k] (NaN where unreachable).
        reachable: S, the point is within l1 - l2 <= r <= l1 + l2 (limits ignored).
        within_limits: S + (2,), that elbow's solution respects both joint ranges.
    """

    q: np.ndarray
    reachable: np.ndarray
    within_limits: np.ndarray


def ik(p: ScaraParams, xy: np.ndarray) -> ScaraIK:
    """Both elbow solutions of every position.

    theta2 = -/+ 2 atan2(sqrt((l1 + l2)^2 - r^2), sqrt(r^2 - (l1 - l2)^2)) (half-angle form,
    each difference of squares factored, so theta2 stays accurate near the boundary where
    acos loses half the digits), theta1 = atan2(y, x) - atan2(l2 s2, l1 + l2 c2), wrapped to
    (-pi, pi]. Points within BOUNDARY_TOL (relative) outside the annulus count as on it.
    """
    xy = finite_vectors(xy, 2, "position")
    x, y = xy[..., 0], xy[..., 1]
    r = np.hypot(x, y)
    inner, outer = p.reach
    far = (outer - r) * (outer + r)
    near = (r - inner) * (r + inner)
    reachable = (far >= -BOUNDARY_TOL * outer**2) & (near >= -BOUNDARY_TOL * outer**2)
    half = np.arctan2(np.sqrt(np.maximum(far, 0.0)), np.sqrt(np.maximum(near, 0.0)))
    phi = np.arctan2(y, x)
    out = np.empty(xy.shape[:-1] + (2, 2))
    for k, sign in enumerate((-1.0, 1.0)):  # ELBOWS order: up (theta2 <= 0), down
        t2 = sign * 2.0 * half
        t1 = phi - np.arctan2(p.l2 * np.sin(t2), p.l1 + p.l2 * np.cos(t2))
        t1 = np.where(t1 <= -np.pi, t1 + 2 * np.pi, np.where(t1 > np.pi, t1 - 2 * np.pi, t1))
        out[..., k, 0] = t1
        out[..., k, 1] = t2
    out[~reachable] = np.nan
    lo, hi = np.asarray(p.lower), np.asarray(p.upper)
    with np.errstate(invalid="ignore"):
        within = np.all((out >= lo - LIMIT_TOL) & (out <= hi + LIMIT_TOL), axis=-1) & reachable[..., None]
    return ScaraIK(out, reachable, within)


def ik_elbow(p: ScaraParams, x: float, y: float, elbow: float) -> tuple[float, float] | None:
    """One elbow's IK solution of one point, scalar (for real-time loops): the formulas of `ik`.

    Args:
        elbow: the sign of theta2, -1 (ELBOWS[0], "up") or +1 ("down").

    Returns:
        (theta1, theta2) [rad], theta1 wrapped to (-pi, pi]; None outside the annulus
        (beyond BOUNDARY_TOL, as in `ik`). Joint limits are not checked.
    """
    r = math.hypot(x, y)
    inner, outer = abs(p.l1 - p.l2), p.l1 + p.l2
    far = (outer - r) * (outer + r)
    near = (r - inner) * (r + inner)
    tol = BOUNDARY_TOL * outer * outer
    if far < -tol or near < -tol:
        return None
    t2 = math.copysign(2.0 * math.atan2(math.sqrt(max(far, 0.0)), math.sqrt(max(near, 0.0))), elbow)
    t1 = math.atan2(y, x) - math.atan2(p.l2 * math.sin(t2), p.l1 + p.l2 * math.cos(t2))
    if t1 <= -math.pi:
        t1 += 2 * math.pi
    elif t1 > math.pi:
        t1 -= 2 * math.pi
    return t1, t2


def ellipse_point(p: ScaraParams, t1: float, t2: float) -> tuple[float, float, tuple[float, float]]:
    """The manipulability ellipse at one configuration, scalar (for real-time loops): the closed
    forms of `manipulability` (r_min = |l1 l2 s2| / r_max, accurate up to the singularity).

    Returns:
        (r_min, r_max [m], unit direction of the minor axis, canonical sign as in `manipulability`).
    """
    s2, c2 = math.sin(t2), math.cos(t2)
    ls, lc = p.l2 * s2, p.l2 * c2
    reach = p.l1 + lc
    a = 2.0 * ls * ls
    b = -ls * (reach + lc)
    c = reach * reach + lc * lc
    half_diff = 0.5 * (a - c)
    r_max = math.sqrt(0.5 * (a + c) + math.hypot(half_diff, b))
    r_min = abs(p.l1 * p.l2 * s2) / r_max if r_max > 0 else 0.0
    psi = 0.5 * math.atan2(b, half_diff) + t1
    mx, my = -math.sin(psi), math.cos(psi)
    sign = math.copysign(1.0, mx if abs(mx) >= abs(my) else my)
    return r_min, r_max, (mx * sign, my * sign)


class IKSolution(NamedTuple):
    """One IK solution of a single point: joint angles [rad], elbow label, limit check."""

    q: tuple[float, float]
    elbow: str
    within_limits: bool
    violations: tuple[str, ...]


class IKAnswer(NamedTuple):
    """IK of a single point: `reachable` means some solution respects the joint limits."""

    reachable: bool
    solutions: tuple[IKSolution, ...]
    reason: str | None


def solve_ik(p: ScaraParams, xy: tuple[float, float] | np.ndarray) -> IKAnswer:
    """IK of one position with per-solution limit reports and, if unreachable, the reason."""
    xy = np.asarray(xy, dtype=float).reshape(-1)
    if xy.size != 2:
        raise InvalidInputError("position", f"expected 2 values (x, y), got {xy.size}")
    res = ik(p, xy)
    r = float(np.hypot(*xy))
    inner, outer = p.reach
    if not res.reachable:
        where = f"beyond the outer radius l1 + l2 = {outer:g} m" if r > outer else (
            f"inside the inner radius |l1 - l2| = {inner:g} m"
        )
        return IKAnswer(False, (), f"distance {r:.6g} m from joint 1 is {where}")
    sols = []
    names = ("joint1", "joint2")
    for k, elbow in enumerate(ELBOWS):
        q = res.q[k]
        viol = tuple(
            f"{names[j]} = {q[j]:.6g} rad outside [{p.lower[j]:.6g}, {p.upper[j]:.6g}]"
            for j in range(2)
            if not p.lower[j] - LIMIT_TOL <= q[j] <= p.upper[j] + LIMIT_TOL
        )
        sols.append(IKSolution((float(q[0]), float(q[1])), elbow, not viol, viol))
    ok = any(s.within_limits for s in sols)
    reason = None if ok else "joint limits rule out both elbows: " + "; ".join(
        f"elbow {s.elbow}: {', '.join(s.violations)}" for s in sols
    )
    return IKAnswer(ok, tuple(sols), reason)
