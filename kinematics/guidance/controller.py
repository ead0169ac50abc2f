"""Manual guidance with singularity-avoiding variable impedance (paper A), one control step at a time.

Per Cartesian axis j, the admittance (paper A eq. 4, K = 0 while guiding) plus the virtual
impedance of eqs. 16-17:

    M a_j = F_j - (B + B_v cos^2 alpha_j) v_j - K_v cos^2 alpha_j (x_j - x_rest,j)
    K_v = B_v = k_max/pi * arctan(gain (r_th - r)) + k_max/2                   (eq. 16)

with r the smaller manipulability radius at the current pose, u its unit direction and
cos^2 alpha_j = u_j^2 (eq. 17: the stiffness along u projected on each axis). Each step:

1. radii and u from the Jacobian at the commanded joint angles;
2. K_v, B_v from eq. 16 (zero with `virtual_impedance=False`);
3. the virtual spring's rest point: the tip position at the step where r first fell below
   r_th (a virtual wall where the warning starts); it is released once r is back above r_th;
4. v_raw = v + a dt (semi-implicit Euler); v = saturate(v_raw) to v_max (default on the speed
   |v|, the ISO 10218-1 hand-guiding limit; `saturation="axis"` clamps each axis); the saturated
   velocity is the one stored and integrated, x += v dt (no wind-up);
5. inverse kinematics of x to a joint command within the joint limits, on the branch the arm is
   on, never another (a branch switch is a jump within one period); a target the current branch
   does not reach within the limits is refused: the tip holds, v = 0 (the arm meets a hard limit,
   as the drives would) and `Step.reason` says why.

M and B are not printed in the paper; the defaults (5 kg, 40 N s/m) give a 0.125 s time constant
and 0.25 m/s under a steady 10 N push. Units of eq. 16 are taken as N/m and N s/m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal, NamedTuple, Protocol

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.mechanisms.scara.closed_form import ScaraParams, ellipse_point, ik_elbow
from kinematics.model.robot import Robot, matrix

Saturation = Literal["norm", "axis"]


@dataclass(frozen=True)
class GuidanceParams:
    """Controller parameters; paper A's values where it gives them.

    Attributes:
        mass: M per axis [kg] (not in the paper).
        damping: B per axis [N s/m] (not in the paper).
        v_max: velocity saturation [m/s] (paper: 0.25, ISO 10218-1).
        saturation: "norm" limits the speed |v|; "axis" clamps each axis to +/- v_max.
        threshold: r_th, smaller radius below which the virtual impedance acts [m] (paper: 0.1).
        k_max: eq. 16's step height [N/m] and [N s/m] (paper: 250).
        gain: eq. 16's arctan slope [1/m] (paper: 1e4).
        dt: control period [s] (1 kHz).
        virtual_impedance: False gives the plain admittance controller (the baseline).
    """

    mass: float = 5.0
    damping: float = 40.0
    v_max: float = 0.25
    saturation: Saturation = "norm"
    threshold: float = 0.1
    k_max: float = 250.0
    gain: float = 1e4
    dt: float = 1e-3
    virtual_impedance: bool = True

    def __post_init__(self) -> None:
        for name in ("mass", "damping", "v_max", "threshold", "k_max", "gain", "dt"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InvalidInputError(name, f"must be positive and finite, got {v}")
        if self.saturation not in ("norm", "axis"):
            raise InvalidInputError("saturation", f"'norm' or 'axis', got {self.saturation!r}")

    def replace(self, **changes: Any) -> GuidanceParams:
        return replace(self, **changes)


def virtual_gain(params: GuidanceParams, r: float) -> float:
    """Eq. 16: K_v = B_v = k_max/pi arctan(gain (r_th - |r|)) + k_max/2, a smooth step from ~0
    (r > r_th) to ~k_max (r < r_th) [N/m, N s/m]."""
    return params.k_max / math.pi * math.atan(params.gain * (params.threshold - abs(r))) + 0.5 * params.k_max


class Kinematics(Protocol):
    """What the controller needs from a robot (task space of dimension `dim`)."""

    dim: int

    def fk(self, q: np.ndarray) -> np.ndarray: ...

    def ellipse(self, q: np.ndarray) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(radii ascending, unit direction of the smallest)."""
        ...

    def ik(self, x: np.ndarray, q_prev: np.ndarray) -> np.ndarray | None:
        """Joint angles reaching x within the limits on q_prev's IK branch, near q_prev; None if
        there are none (never a configuration on another branch)."""
        ...

    def refusal(self, x: np.ndarray, q_prev: np.ndarray) -> str:
        """Why `ik(x, q_prev)` returned None (called only then, off the fast path)."""
        ...

    def rate(self, q_prev: np.ndarray, q_new: np.ndarray, dt: float) -> np.ndarray:
        """Joint velocity [rad/s or m/s] taking q_prev to q_new in dt (shape nv)."""
        ...


class ScaraKinematics:
    """The planar 2R arm through the scalar closed forms of `kinematics.mechanisms.scara.closed_form` (half-angle IK,
    |det J| / r_max radii), allocation-light for a real-time loop.

    IK branch: the elbow sign of theta2. `ik` only answers on q_prev's branch: the two elbows
    meet only on the stretched boundary (theta2 = 0), so any other switch is a jump of 2|theta2|
    within one period. At theta2 = 0 exactly both are the same pose and the nearer one is taken.
    """

    dim = 2
    nq = 2
    """Joint values the controller's q holds (theta1, theta2) [rad]."""

    def __init__(self, sp: ScaraParams) -> None:
        self.sp = sp
        self.l1, self.l2 = sp.l1, sp.l2
        self.lower, self.upper = sp.lower, sp.upper

    def fk(self, q: np.ndarray) -> np.ndarray:
        t1, t12 = q[0], q[0] + q[1]
        return np.array([self.l1 * math.cos(t1) + self.l2 * math.cos(t12),
                         self.l1 * math.sin(t1) + self.l2 * math.sin(t12)])

    def ellipse(self, q: np.ndarray) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Radii (r_min, r_max) and the minor axis' direction (`scara.ellipse_point`)."""
        r_min, r_max, u = ellipse_point(self.sp, float(q[0]), float(q[1]))
        return (r_min, r_max), u

    def _within(self, q: tuple[float, float]) -> bool:
        lo, hi = self.lower, self.upper
        return lo[0] <= q[0] <= hi[0] and lo[1] <= q[1] <= hi[1]

    def _candidates(self, x: np.ndarray, q_prev: np.ndarray) -> list[tuple[float, float]]:
        x0, x1 = float(x[0]), float(x[1])
        if q_prev[1] != 0.0:
            sol = ik_elbow(self.sp, x0, x1, float(q_prev[1]))
            return [] if sol is None else [sol]
        # stretched: both elbows continue from here; the nearer first
        sols = [s for s in (ik_elbow(self.sp, x0, x1, e) for e in (-1.0, 1.0)) if s is not None]
        return sorted(sols, key=lambda s: abs(s[0] - q_prev[0]) + abs(s[1] - q_prev[1]))

    def ik(self, x: np.ndarray, q_prev: np.ndarray) -> np.ndarray | None:
        if q_prev[1] != 0.0:  # the real-time path: one elbow, no lists
            sol = ik_elbow(self.sp, float(x[0]), float(x[1]), float(q_prev[1]))
            return np.array(sol) if sol is not None and self._within(sol) else None
        for sol in self._candidates(x, q_prev):
            if self._within(sol):
                return np.array(sol)
        return None

    def refusal(self, x: np.ndarray, q_prev: np.ndarray) -> str:
        lo, hi = self.lower, self.upper
        branch = "up (theta2 < 0)" if q_prev[1] < 0 else "down (theta2 > 0)" if q_prev[1] > 0 else "either"
        sols = self._candidates(x, q_prev)
        if not sols:
            r = math.hypot(float(x[0]), float(x[1]))
            inner, outer = self.sp.reach
            return f"target at {r:.6g} m from joint 1 is outside the reachable annulus [{inner:g}, {outer:g}] m"
        t1, t2 = sols[0]
        bad = [f"joint{j + 1} = {v:.6g} rad outside [{lo[j]:.6g}, {hi[j]:.6g}]"
               for j, v in enumerate((t1, t2)) if not lo[j] <= v <= hi[j]]
        other = ik_elbow(self.sp, float(x[0]), float(x[1]), -1.0 if q_prev[1] > 0 else 1.0)
        why = f"on the elbow-{branch} branch {', '.join(bad)}"
        if q_prev[1] != 0.0 and other is not None and self._within(other):
            why += (f"; the other elbow (theta2 = {other[1]:.6g} rad) is within the limits, but switching "
                    f"branch within one step would move joint 2 by {abs(other[1] - q_prev[1]):.3g} rad")
        return why

    def rate(self, q_prev: np.ndarray, q_new: np.ndarray, dt: float) -> np.ndarray:
        return (q_new - q_prev) / dt


class SerialKinematics:
    """Any serial URDF through Pinocchio: the tool's translational task (3D) and ellipsoid, IK by
    damped least squares from the previous command, stepped on the configuration manifold
    (`pin.integrate`, so continuous joints - nq = 2, nv = 1 - work) and held within the bounded
    joints' limits. Local, so it stays on q_prev's branch."""

    dim = 3

    def __init__(self, robot: Robot, frame: str | None = None, damping: float = 1e-6) -> None:
        import pinocchio as pin

        self.pin = pin
        self.robot = robot
        self.model = robot.model
        self.data = self.model.createData()
        self.fid = robot.frame_id(frame)
        self.nq = self.model.nq  # q is a Pinocchio configuration
        # configuration-space indices and bounds of the joints that have finite limits
        bounded = [d for d in robot.dofs if np.isfinite(d.lower) and np.isfinite(d.upper)]
        self.bounded_q = np.array([d.idx_q for d in bounded], dtype=int)
        self.lower = np.array([d.lower for d in bounded])
        self.upper = np.array([d.upper for d in bounded])
        self.lam2 = damping
        self.tol = 1e-6

    def _jac(self, q: np.ndarray) -> np.ndarray:
        pin = self.pin
        return matrix(pin.computeFrameJacobian(self.model, self.data, q, self.fid, pin.LOCAL_WORLD_ALIGNED),
                      self.model.nv)[:3]

    def fk(self, q: np.ndarray) -> np.ndarray:
        self.pin.framesForwardKinematics(self.model, self.data, q)
        return self.data.oMf[self.fid].translation.copy()

    def ellipse(self, q: np.ndarray) -> tuple[tuple[float, ...], tuple[float, ...]]:
        J = self._jac(q)
        w, V = np.linalg.eigh(J @ J.T)
        return tuple(np.sqrt(np.maximum(w, 0.0)).tolist()), tuple(V[:, 0].tolist())

    def ik(self, x: np.ndarray, q_prev: np.ndarray, iters: int = 20, tol: float = 1e-10) -> np.ndarray | None:
        q = q_prev.copy()
        for _ in range(iters):
            e = x - self.fk(q)
            if e @ e < tol * tol:
                return q
            J = self._jac(q)
            dv = J.T @ np.linalg.solve(J @ J.T + self.lam2 * np.eye(3), e)
            q = self.pin.integrate(self.model, q, dv)
            q[self.bounded_q] = np.clip(q[self.bounded_q], self.lower, self.upper)
        return q if np.linalg.norm(x - self.fk(q)) < self.tol else None

    def refusal(self, x: np.ndarray, q_prev: np.ndarray) -> str:
        return (f"no configuration within the joint limits near the previous command reaches the target "
                f"within {self.tol:g} m (damped least squares)")

    def rate(self, q_prev: np.ndarray, q_new: np.ndarray, dt: float) -> np.ndarray:
        return self.pin.difference(self.model, q_prev, q_new) / dt


class Step(NamedTuple):
    """What one control step produced (SI units)."""

    x: np.ndarray
    v_raw: np.ndarray
    v: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    radii: tuple[float, ...]
    direction: tuple[float, ...]
    k_v: float
    saturated: bool
    blocked: bool
    reason: str | None = None
    """Why the step was refused (`blocked`), else None."""


@dataclass
class Controller:
    """The guidance controller's state; `step(force)` is one real-time period."""

    kin: Kinematics
    params: GuidanceParams
    q: np.ndarray
    x: np.ndarray = field(init=False)
    v: np.ndarray = field(init=False)
    rest: np.ndarray | None = field(init=False, default=None)

    def __post_init__(self) -> None:
        q = np.array(self.q, dtype=float)
        n = getattr(self.kin, "nq", None)  # a Kinematics of one's own may not say
        if q.ndim != 1 or (n is not None and q.size != n) or not np.all(np.isfinite(q)):
            raise InvalidInputError("q", f"need {n if n is not None else 'the robot'}'s finite joint values (one "
                                         f"configuration), got {np.asarray(self.q).tolist()}")
        self.q = q
        self.x = self.kin.fk(self.q)
        self.v = np.zeros(self.kin.dim)

    def step(self, force: np.ndarray) -> Step:
        P = self.params
        f = np.asarray(force, dtype=float)
        if f.shape != (self.kin.dim,) or not np.all(np.isfinite(f)):
            raise InvalidInputError("force", f"need {self.kin.dim} finite components [N], got {force!r}")
        radii, u = self.kin.ellipse(self.q)
        r = radii[0]
        k = virtual_gain(P, r) if P.virtual_impedance else 0.0
        if P.virtual_impedance and r < P.threshold:
            if self.rest is None:
                self.rest = self.x.copy()
        else:
            self.rest = None
        dt, m, b = P.dt, P.mass, P.damping
        x, v = self.x, self.v
        v_raw = np.empty_like(v)
        for j in range(self.kin.dim):
            c2 = u[j] * u[j]
            spring = -k * c2 * (x[j] - self.rest[j]) if self.rest is not None else 0.0
            v_raw[j] = v[j] + dt * (f[j] + spring - (b + k * c2) * v[j]) / m
        speed = math.sqrt(float(v_raw @ v_raw))
        if P.saturation == "norm":
            v_new = v_raw * (P.v_max / speed) if speed > P.v_max else v_raw.copy()
        else:
            v_new = np.clip(v_raw, -P.v_max, P.v_max)
        saturated = bool(np.any(v_new != v_raw))
        x_new = x + dt * v_new
        q_new = self.kin.ik(x_new, self.q)
        blocked = q_new is None
        reason = None
        if q_new is None:
            reason = self.kin.refusal(x_new, self.q)
            x_new, v_new, q_new = x.copy(), np.zeros_like(v_new), self.q
        qdot = self.kin.rate(self.q, q_new, dt)
        self.x, self.v, self.q = x_new, v_new, q_new
        return Step(x_new, v_raw, v_new, q_new, qdot, radii, u, k, saturated, blocked, reason)
