"""Velocities and singularities of the batched closed-loop solver's solutions (`LoopSingularities`).

**Singularities** (Gosselin & Angeles), from the Jacobian U of all rows (closures, orientation,
task) at a solution, U_a / U_p its actuated / passive columns, and P the task rows:

* type I (an actuator rate undetermined by the platform's): iota_I = sigma_min((I - U_p U_p^+) U_a D^-1)
  with D the norms of U_a's columns: 0 iff some actuator can move with the end effector fixed;
  in [0, 1]; a passive freedom that moves no actuator (a gimbal-locked universal joint) is ignored;
* type II (locked actuators do not hold the platform): iota_II = min over passive rates v with
  P v != 0 of |A v| / |P v|, A the closure and orientation rows: 0 iff the end effector can move
  with the actuators locked; dimensionless (rows in metres), not bounded by 1; +inf where no
  passive rate moves the end effector (a gantry's slides carry it: nothing to hold);
* type III: both. A pose is singular when a measure is <= SINGULAR_TOL.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.generic.loop_batch.model import LoopModel
from kinematics.generic.singularity import SINGULAR_TOL


class Singularities(NamedTuple):
    """Singularity measures per target and branch (NaN where the branch is absent).

    Attributes:
        iota_I, iota_II: (N, B) the scale-free measures (see the module docstring).
        types: (N, B) 0 none, 1 type I, 2 type II, 3 type III (-1 absent), SINGULARITY_TYPES.
    """

    iota_I: np.ndarray
    iota_II: np.ndarray
    types: np.ndarray


class LoopSingularities(LoopModel):
    """Forward and inverse Jacobians and singularity measures at solutions (a part of `LoopBatch`)."""

    # -- velocities and singularities -----------------------------------------------------------
    def _split(self, points: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        self.require_unheld("Jacobians and singularity measures")
        p = self._points(points)
        x = np.asarray(x, dtype=float)
        if x.shape[:1] != (len(p),) or x.shape[-1] != self.n:
            raise InvalidInputError("x", f"expected ({len(p)}, [B,] {self.n}) joint values, got {x.shape}")
        xb = x.reshape(len(p), -1, self.n)
        B = xb.shape[1]
        ok = np.all(np.isfinite(xb), axis=-1)
        t = np.repeat(p, B, axis=0)
        _, J, _ = self.evaluate(t, np.nan_to_num(xb.reshape(-1, self.n)))
        return J.reshape(len(p), B, self._m, self.n), ok, xb

    def jacobians(self, points: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(forward, inverse) Jacobians at solutions x (N, [B,] n) of targets (N, d).

        forward: (N, B, d, a): task velocity per actuator rate (locked-actuator passive rates
        eliminated by least squares; meaningless at type II). inverse: (N, B, a, d): actuator
        rates per task velocity (meaningless at type I). NaN where x is NaN.
        """
        J, ok, _ = self._split(points, x)
        a, pa = self.actuated, self.passive
        c = self._m - self.task_dim
        U_inv = np.linalg.pinv(J, rcond=1e-13)  # (N, B, n, m)
        inverse = U_inv[..., a, c:]
        A = J[..., :c, :]
        Pm = J[..., c:, :]
        vp = -np.linalg.pinv(A[..., pa], rcond=1e-13) @ A[..., a]  # (N, B, np, a)
        forward = Pm[..., a] + Pm[..., pa] @ vp
        nan = ~ok[..., None, None]
        return np.where(nan, np.nan, forward), np.where(nan, np.nan, inverse)

    def singularities(self, points: np.ndarray, x: np.ndarray, tol: float = SINGULAR_TOL) -> Singularities:
        """Gosselin-Angeles measures and types at solutions x (N, [B,] n) (module docstring)."""
        J, ok, _ = self._split(points, x)
        a, pa = self.actuated, self.passive
        c = self._m - self.task_dim
        Ua, Up = J[..., a], J[..., pa]
        Ua = Ua / np.maximum(np.linalg.norm(Ua, axis=-2, keepdims=True), 1e-300)
        proj = Ua - Up @ (np.linalg.pinv(Up, rcond=1e-10) @ Ua)
        iota_I = np.linalg.svd(proj, compute_uv=False)[..., -1]
        A, P = J[..., :c, :][..., pa], J[..., c:, :][..., pa]
        r = 0
        if len(pa) and P.size:
            _, s, Vt = np.linalg.svd(P, full_matrices=True)
            r = int(np.max(np.sum(s > 1e-10 * np.maximum(s[..., :1], 1e-300), axis=-1)))
        if r == 0:  # no passive rate moves the end effector: locked actuators always hold it
            iota_II = np.full(ok.shape, np.inf)
        else:
            V = np.swapaxes(Vt, -1, -2)
            Y, Z = V[..., :r], V[..., r:]
            AY, AZ = A @ Y, A @ Z
            QAY = AY - AZ @ (np.linalg.pinv(AZ, rcond=1e-10) @ AY)
            iota_II = np.linalg.svd(QAY / s[..., None, :r], compute_uv=False)[..., -1]
        iota_I = np.where(ok, iota_I, np.nan)
        iota_II = np.where(ok, iota_II, np.nan)
        types = np.where(ok, (iota_I <= tol).astype(np.int8) + 2 * (iota_II <= tol).astype(np.int8), -1)
        return Singularities(iota_I, iota_II, types.astype(np.int8))
