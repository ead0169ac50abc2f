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
   on; a target no branch reaches within the limits is refused: the tip holds and v = 0 (the arm
   meets a hard limit, as the drives would).

M and B are not printed in the paper; the defaults (5 kg, 40 N s/m) give a 0.125 s time constant
and 0.25 m/s under a steady 10 N push. Units of eq. 16 are taken as N/m and N s/m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal, NamedTuple, Protocol

import numpy as np

from .errors import InvalidInputError

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

    def replace(self, **changes: object) -> GuidanceParams:
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
        """Joint angles reaching x within the limits, near q_prev; None if there are none."""
        ...


class ScaraKinematics:
    """Closed forms of the planar 2R arm, scalar and allocation-light for a real-time loop."""

    dim = 2

    def __init__(self, sp: object) -> None:
        self.sp = sp
        self.l1, self.l2 = sp.l1, sp.l2  # type: ignore[attr-defined]
        self.lower, self.upper = sp.lower, sp.upper  # type: ignore[attr-defined]

    def fk(self, q: np.ndarray) -> np.ndarray:
        t1, t12 = q[0], q[0] + q[1]
        return np.array([self.l1 * math.cos(t1) + self.l2 * math.cos(t12),
                         self.l1 * math.sin(t1) + self.l2 * math.sin(t12)])

    def ellipse(self, q: np.ndarray) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Radii sqrt(eig(J J^T)) and the smaller one's direction, from the 2 x 2 entries."""
        s1, c1 = math.sin(q[0]), math.cos(q[0])
        s12, c12 = math.sin(q[0] + q[1]), math.cos(q[0] + q[1])
        j11, j12 = -self.l1 * s1 - self.l2 * s12, -self.l2 * s12
        j21, j22 = self.l1 * c1 + self.l2 * c12, self.l2 * c12
        a, b, c = j11 * j11 + j12 * j12, j11 * j21 + j12 * j22, j21 * j21 + j22 * j22
        mean, half = 0.5 * (a + c), math.hypot(0.5 * (a - c), b)
        lo, hi = max(mean - half, 0.0), mean + half
        # eigenvector of lo: the better conditioned of (b, lo - a) and (lo - c, b)
        v1, v2 = (b, lo - a), (lo - c, b)
        vx, vy = v1 if math.hypot(*v1) >= math.hypot(*v2) else v2
        n = math.hypot(vx, vy)
        u = (vx / n, vy / n) if n > 0 else (1.0, 0.0)
        return (math.sqrt(lo), math.sqrt(hi)), u

    def ik(self, x: np.ndarray, q_prev: np.ndarray) -> np.ndarray | None:
        l1, l2 = self.l1, self.l2
        r2 = x[0] * x[0] + x[1] * x[1]
        c2 = (r2 - l1 * l1 - l2 * l2) / (2 * l1 * l2)
        if c2 > 1.0 or c2 < -1.0:
            return None
        mag = math.acos(c2)
        best = None
        for t2 in ((mag, -mag) if q_prev[1] >= 0 else (-mag, mag)):  # stay on the current elbow first
            t1 = math.atan2(x[1], x[0]) - math.atan2(l2 * math.sin(t2), l1 + l2 * math.cos(t2))
            t1 = (t1 + math.pi) % (2 * math.pi) - math.pi
            if self.lower[0] <= t1 <= self.upper[0] and self.lower[1] <= t2 <= self.upper[1]:
                best = np.array([t1, t2])
                break
        return best


class SerialKinematics:
    """Any serial URDF through Pinocchio: the tool's translational task (3D) and ellipsoid, IK by
    damped least squares from the previous command, clipped to the joint limits."""

    dim = 3

    def __init__(self, robot: object, frame: str | None = None, damping: float = 1e-6) -> None:
        import pinocchio as pin

        self.pin = pin
        self.robot = robot
        self.model = robot.model  # type: ignore[attr-defined]
        self.data = self.model.createData()
        self.fid = robot.frame_id(frame)  # type: ignore[attr-defined]
        self.lower = np.where(np.isfinite(self.model.lowerPositionLimit), self.model.lowerPositionLimit, -1e9)
        self.upper = np.where(np.isfinite(self.model.upperPositionLimit), self.model.upperPositionLimit, 1e9)
        self.lam2 = damping

    def _jac(self, q: np.ndarray) -> np.ndarray:
        pin = self.pin
        return pin.computeFrameJacobian(self.model, self.data, q, self.fid, pin.LOCAL_WORLD_ALIGNED)[:3]

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
            dq = J.T @ np.linalg.solve(J @ J.T + self.lam2 * np.eye(3), e)
            q = np.clip(q + dq, self.lower, self.upper)
        return q if np.linalg.norm(x - self.fk(q)) < 1e-6 else None


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
        self.q = np.asarray(self.q, dtype=float).copy()
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
        if blocked:
            x_new, v_new, q_new = x.copy(), np.zeros_like(v_new), self.q
        qdot = (q_new - self.q) / dt
        self.x, self.v, self.q = x_new, v_new, q_new
        return Step(x_new, v_raw, v_new, q_new, qdot, radii, u, k, saturated, blocked)
