"""Closed forms of the planar five-bar linkage (a test oracle for the generic closed-loop path).

Chain i (i = 1, 2): base pivot A_i, proximal link of length a_i at absolute angle theta_i, elbow
B_i = A_i + a_i u(theta_i), distal link of length b_i at absolute angle phi_i, tip
P = B_i + b_i u(phi_i), u(t) = (cos t, sin t). Both chains meet at P.

* IK (P given): B_i is an intersection of circle(A_i, a_i) and circle(P, b_i): two per chain,
  four working modes (s_1, s_2), s_i = +1 when B_i lies left of the line A_i -> P.
* FK (theta given): P is an intersection of circle(B_1, b_1) and circle(B_2, b_2): two assembly
  modes, s = +1 when P lies left of the line B_1 -> B_2.
* Velocities: differentiating |P - B_i|^2 = b_i^2 with dB_i = e_z x (B_i - A_i) dtheta_i gives
  J_x dP = J_q dtheta, J_x = [(P - B_1)^T; (P - B_2)^T], J_q = diag((P - B_i) . (e_z x (B_i - A_i))).
  Type I (serial) singularity: det J_q = 0 (a chain folded or stretched, sin(phi_i - theta_i) = 0);
  type II (parallel): det J_x = 0 (distal links aligned, sin(phi_2 - phi_1) = 0).
  The distal link 1 turns at dphi_1 = (e_z x (P - B_1)) . (dP - dB_1) / b_1^2.

The geometry is read from a loaded model of the fixture (pivot, elbow and tip positions at the
all-zero configuration), never typed in a second time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin


def u(t: float) -> np.ndarray:
    return np.array([np.cos(t), np.sin(t)])


def cross(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def perp(a: np.ndarray) -> np.ndarray:
    """e_z x a."""
    return np.array([-a[1], a[0]])


def circles(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float, side: int) -> np.ndarray | None:
    """The intersection of circle(c1, r1) and circle(c2, r2) on the left (side = +1) or the right
    (-1) of the line c1 -> c2; None if the circles do not meet."""
    d = c2 - c1
    r = float(np.linalg.norm(d))
    x = (r1**2 - r2**2 + r**2) / (2 * r)
    h2 = r1**2 - x**2
    if h2 < 0:
        return None
    return c1 + x * d / r + side * np.sqrt(h2) * perp(d) / r


@dataclass(frozen=True)
class FiveBar:
    A: np.ndarray  # 2 x 2 base pivots [m]
    a: np.ndarray  # proximal lengths [m]
    b: np.ndarray  # distal lengths [m]
    theta0: np.ndarray  # absolute proximal angles at motor value 0 [rad]
    phi0: np.ndarray  # absolute distal angles at the all-zero configuration [rad]

    @classmethod
    def from_robot(cls, robot, motors=("mot1", "mot2"), elbows=("free1", "free2"),
                   tips=("closedloop1_A", "closedloop3D_B")) -> FiveBar:
        model = robot.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        A = np.array([data.oMi[model.getJointId(m)].translation[:2] for m in motors])
        B = np.array([data.oMi[model.getJointId(e)].translation[:2] for e in elbows])
        P = np.array([data.oMf[model.getFrameId(t)].translation[:2] for t in tips])
        theta0 = np.array([np.arctan2(*(B[i] - A[i])[::-1]) for i in range(2)])
        phi0 = np.array([np.arctan2(*(P[i] - B[i])[::-1]) for i in range(2)])
        return cls(A, np.linalg.norm(B - A, axis=1), np.linalg.norm(P - B, axis=1), theta0, phi0)

    # -- positions -------------------------------------------------------------------------------
    def reach(self, P: np.ndarray) -> np.ndarray:
        """Signed reach slack [m] of each chain at points P (..., 2) -> (..., 2):
        min(a_i + b_i - |P - A_i|, |P - A_i| - |a_i - b_i|), >= 0 where chain i reaches P (its joints
        turn freely, so reach is its only limit); its magnitude is the distance to the nearer of
        chain i's two reach circles."""
        d = np.linalg.norm(np.asarray(P, dtype=float)[..., None, :] - self.A, axis=-1)
        return np.minimum(self.a + self.b - d, d - np.abs(self.a - self.b))

    def elbows(self, theta: np.ndarray) -> np.ndarray:
        return np.array([self.A[i] + self.a[i] * u(theta[i]) for i in range(2)])

    def fk(self, motors: np.ndarray, mode: int) -> np.ndarray | None:
        """Tip P for motor values, assembly mode +1/-1 (P left/right of B_1 -> B_2)."""
        B = self.elbows(self.theta0 + np.asarray(motors))
        return circles(B[0], self.b[0], B[1], self.b[1], mode)

    def ik(self, P: np.ndarray, modes: tuple[int, int]) -> np.ndarray | None:
        """Absolute proximal angles reaching P in working mode (s_1, s_2); None if out of reach."""
        out = []
        for i in range(2):
            B = circles(self.A[i], self.a[i], P, self.b[i], modes[i])
            if B is None:
                return None
            out.append(np.arctan2(*(B - self.A[i])[::-1]))
        return np.array(out)

    def distal_angles(self, theta: np.ndarray, P: np.ndarray) -> np.ndarray:
        B = self.elbows(theta)
        return np.array([np.arctan2(*(P - B[i])[::-1]) for i in range(2)])

    def joint_values(self, theta: np.ndarray, P: np.ndarray) -> dict[str, float]:
        """Every joint of the fixture (mot1, free1, mot2, free2, free3) at absolute angles theta and
        tip P: joint values are the changes of relative angles from the all-zero configuration."""
        phi = self.distal_angles(theta, P)
        rel = phi - theta - (self.phi0 - self.theta0)
        free3 = (phi[0] - phi[1]) - (self.phi0[0] - self.phi0[1])  # tip_2 turns with distal_1
        wrap = lambda x: float((x + np.pi) % (2 * np.pi) - np.pi)
        m = theta - self.theta0
        return {"mot1": wrap(m[0]), "free1": wrap(rel[0]), "mot2": wrap(m[1]), "free2": wrap(rel[1]),
                "free3": wrap(free3)}

    # -- velocities ------------------------------------------------------------------------------
    def jacobians(self, theta: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(J_x, J_q) with J_x dP = J_q dtheta."""
        B = self.elbows(theta)
        Jx = np.array([P - B[0], P - B[1]])
        Jq = np.diag([(P - B[i]) @ perp(B[i] - self.A[i]) for i in range(2)])
        return Jx, Jq

    def twist(self, theta: np.ndarray, P: np.ndarray) -> np.ndarray:
        """3 x 2: (dP_x, dP_y, dphi_1) per motor rate."""
        Jx, Jq = self.jacobians(theta, P)
        G = np.linalg.solve(Jx, Jq)
        B = self.elbows(theta)
        dB1 = np.outer(perp(B[0] - self.A[0]), [1.0, 0.0])  # only motor 1 moves B_1
        w = perp(P - B[0]) @ (G - dB1) / self.b[0] ** 2
        return np.vstack([G, w])

    def singularity_indices(self, theta: np.ndarray, P: np.ndarray) -> tuple[float, float]:
        """(type I, type II): min_i |sin(phi_i - theta_i)| and |sin(phi_2 - phi_1)|; 0 at the
        singularity, 1 at the best-conditioned pose."""
        phi = self.distal_angles(theta, P)
        return float(np.min(np.abs(np.sin(phi - theta)))), float(abs(np.sin(phi[1] - phi[0])))
