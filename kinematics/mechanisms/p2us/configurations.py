"""The 3-[P2(US)] URDF tree's configurations at many platform positions, compiled: the same values
as `urdf.configurations_at`'s closed forms (`closed_form.limb_ik`, `passive_angles`,
`three_limb.tree_value_arrays`) in one pass per point, without the (N, 3, 2, 3) temporaries (the
collision-free exact columns evaluate millions of points)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from kinematics.mechanisms.p2us.closed_form import P2USParams
from kinematics.mechanisms.three_limb.closed_form import BOUNDARY_TOL, mode_index
from kinematics.mechanisms.three_limb.modes import MODE_ROOTS, points
from kinematics.mechanisms.three_limb.urdf import LIMBS, RODS

SLIDER, U_THETA, U_PHI, S_1, S_2, S_3 = range(6)
"""What a configuration coordinate holds: limb i's carriage, rod angles theta, phi (both rods of
a limb alike), the platform's spherical joint (s_1 = -phi_1, s_2 = centre - theta_1, s_3 = 0)."""


def coordinate_codes(model: Any, actuator: str = "slider", first: str = "u_theta") -> tuple[np.ndarray, np.ndarray]:
    """(code, limb) per configuration coordinate of `model` (each joint one coordinate), by joint
    name as `three_limb.tree_value_arrays` names them; KeyError for a joint it does not name."""
    names = {f"{actuator}_{i}": (SLIDER, i - 1) for i in LIMBS}
    for i in LIMBS:
        for k in RODS:
            names[f"{first}_{i}_{k}"] = (U_THETA, i - 1)
            names[f"u_phi_{i}_{k}"] = (U_PHI, i - 1)
    names.update({"s_1": (S_1, 0), "s_2": (S_2, 0), "s_3": (S_3, 0)})
    code = np.zeros(model.nq, np.int64)
    limb = np.zeros(model.nq, np.int64)
    for j in range(1, model.njoints):
        code[model.idx_qs[j]], limb[model.idx_qs[j]] = names[model.names[j]]
    return code, limb


def configurations(params: P2USParams, model: Any, pts: np.ndarray, mode: str) -> np.ndarray:
    """Configurations (N, nq) of the p2us URDF `model` with the platform at `pts` (N, 3) [m] in
    working mode `mode` (NaN in the values of a limb that cannot reach), as `urdf.configurations_at`."""
    p = np.ascontiguousarray(points(pts).reshape(-1, 3))
    out = np.empty((len(p), model.nq))
    configurations_kernel(p, *kernel_data(params, model, mode), out)  # type: ignore[call-arg]
    return out


def kernel_data(params: P2USParams, model: Any, mode: str) -> tuple[np.ndarray, ...]:
    """`configurations_kernel`'s arguments between the positions and the output: e, w, t,
    geometry, roots, code, limb (for kernels that pose the tree at points of their own)."""
    code, limb = coordinate_codes(model)
    geometry = np.array([params.d - params.b, params.L, params.theta_zero, params.theta_joint_centre,
                         BOUNDARY_TOL])
    return (np.ascontiguousarray(params.e, dtype=float), np.ascontiguousarray(params.w, dtype=float),
            np.ascontiguousarray(params.t, dtype=float), geometry,
            np.ascontiguousarray(MODE_ROOTS[mode_index(mode)], dtype=np.int64), code, limb)


@njit(cache=True)
def configurations_kernel(p, e, w, t, geometry, roots, code, limb, out):  # pragma: no cover - compiled
    """out (N, nq) from platform positions p (N, 3): per limb i, v = p + (d - b) e_i, A = v.w_i,
    the IK root q = A +/- sqrt(A^2 - |v|^2 + L^2) of `roots[i]` (NaN beyond the reach tolerance),
    the rod direction n = (v - q w_i) / L, phi = asin(-n.t_i), theta = atan2(-n_z, -n.e_i) -
    theta_zero within pi of the joint centre."""
    db, L, theta_zero, centre, tol = geometry[0], geometry[1], geometry[2], geometry[3], geometry[4]
    val = np.empty((3, 3))
    for n in range(p.shape[0]):
        for i in range(3):
            vx, vy, vz = p[n, 0] + db * e[i, 0], p[n, 1] + db * e[i, 1], p[n, 2] + db * e[i, 2]
            A = vx * w[i, 0] + vy * w[i, 1] + vz * w[i, 2]
            disc = A * A - ((vx * vx + vy * vy + vz * vz) - L * L)
            root = math.sqrt(max(disc, 0.0)) if disc >= -tol * L * L else np.nan
            q = A + root if roots[i] == 0 else A - root
            nx, ny, nz = (vx - q * w[i, 0]) / L, (vy - q * w[i, 1]) / L, (vz - q * w[i, 2]) / L
            ne = nx * e[i, 0] + ny * e[i, 1] + nz * e[i, 2]
            nt = nx * t[i, 0] + ny * t[i, 1] + nz * t[i, 2]
            theta = math.atan2(-nz, -ne) - theta_zero
            theta = (theta - centre + math.pi) % (2 * math.pi) + centre - math.pi
            val[i, 0], val[i, 1], val[i, 2] = q, theta, math.asin(min(max(-nt, -1.0), 1.0))
        for k in range(code.shape[0]):
            c = code[k]
            if c <= 2:
                out[n, k] = val[limb[k], c]
            elif c == 3:
                out[n, k] = -val[0, 2]
            elif c == 4:
                out[n, k] = centre - val[0, 1]
            else:
                out[n, k] = 0.0


def kernels() -> tuple[Any, ...]:
    """The compiled kernels of this module (for `kinematics.jit`)."""
    return (configurations_kernel,)


__all__ = ["configurations", "configurations_kernel", "coordinate_codes", "kernel_data"]
