"""Write and read the URDF + loop sidecar of a Delta robot design (3-RUU, Clavel).

Tree (limb i = 1..3, rod k = 1, 2; y_k = -/+ s/2 along t_i; see docs/delta.md):

    base
     +- limb_i_joint      fixed     rpy (0, 0, alpha_i)                  frame x = e_i, y = t_i
         +- actuator_i    revolute  xyz (R, 0, 0), axis y                theta (down positive)
             +- elbow_i_k_joint  fixed  xyz (la, y_k, 0) rpy (0, sigma, 0)   x = elbow socket axis
                 +- u_psi_i_k   revolute  axis y   (in the limb's plane, from the socket axis)
                     +- u_phi_i_k   revolute  axis z   (out of the plane, towards t_i)
                         +- tip_i_k_joint  fixed  xyz (lb, 0, 0)         link tip_i_k (ball centre)
    tip_1_1 -> s_1 (z) -> s_2 (y) -> s_3 (x) -> platform_joint (fixed) -> platform
    platform -> pmount_i_joint (rpy (0, 0, alpha_i)) -> anchor_i_k_joint (xyz (r, y_k, 0))
             -> psocket_i_joint (xyz (r, 0, 0), rpy (0, kappa, 0)): z = platform socket axis

The elbow ball joint is modelled as a universal joint (u_psi, u_phi) whose zero is the socket
axis: a rod's spin about its own axis between two ball joints moves nothing, so a U + S rod is
the same mechanism without the idle freedom. Both U angles are limited to [-cone, cone], the
box around the ball joint's cone cos(psi) cos(phi) >= cos(cone); the closed forms check the
cone itself, and read its half-angle back from these limits. The platform hangs from rod (1, 1)
through a spherical joint modelled as three revolute joints; the fixed `platform_joint` makes
s = 0 the forearm pointing straight down in limb 1's plane, so the gimbal lock (s_2 = +/-90 deg)
needs that forearm horizontal, outside the platform cone whenever cone + kappa < 90 deg. The
other five rod tips are closed onto their anchors by point constraints in the sidecar. Every
design number appears verbatim in exactly one place, written as the shortest text of the same
float, so generate -> read round-trips exactly. The shared parts of the tree, the sidecar and the
writing are `kinematics.mechanisms.three_limb.urdf`'s.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from kinematics.mechanisms.delta.closed_form import MECHANISM, DeltaParams, ik, limb_ik, passive_angles
from kinematics.mechanisms.three_limb import urdf as three_limb
from kinematics.mechanisms.three_limb.reader import LayoutReader
from kinematics.mechanisms.three_limb.urdf import LIMBS as LIMBS
from kinematics.mechanisms.three_limb.urdf import RODS as RODS
from kinematics.mechanisms.three_limb.urdf import SPHERICAL as SPHERICAL
from kinematics.mechanisms.three_limb.urdf import CollisionSizes
from kinematics.mechanisms.three_limb.urdf import rod_offset as rod_offset
from kinematics.model.urdf_xml import (
    UrdfBuilder,
    axis_of,
    capsule,
    limit_of,
    num,
    origin_of,
    rot_y,
    rot_z,
    visual,
)

SIZES = CollisionSizes(arm_radius=0.015, plate_overhang=0.05)
"""Default collision sizes (`kinematics urdf delta --rod-radius ...`): rods 6 mm, upper arms 15 mm
in radius, a 20 mm base plate 50 mm beyond R, the platform's sphere 20 mm beyond r."""


def _platform_mount(params: DeltaParams) -> tuple[np.ndarray, np.ndarray]:
    """Fixed placement (translation, rotation) from the s_3 body to the platform frame."""
    R_s3 = rot_z(params.alpha[0]) @ rot_y(math.pi / 2)  # s = 0: rod (1, 1) straight down
    anchor = params.r * params.e[0] + rod_offset(1, params.rod_spacing) * params.t[0]
    return three_limb.platform_mount(R_s3, anchor)


MATERIALS = {"frame": "0.6 0.6 0.65 1", "arm": "0.95 0.55 0.1 1", "rod": "0.2 0.45 0.85 1",
             **three_limb.JOINT_MATERIAL, "platform": "0.85 0.2 0.2 1"}


def command(params: DeltaParams) -> str:
    """How this design is written, for the files' headers."""
    return "`kinematics urdf delta`" + (", default design" if params == DeltaParams() else " with design flags")


def urdf_text(params: DeltaParams, name: str = "delta", sizes: CollisionSizes = SIZES) -> str:
    """The URDF of a Delta design (`xml.etree.ElementTree`, indented), with collision shapes of
    `sizes` (`three_limb.urdf.CollisionSizes`): base plate, upper arms, rods, platform."""
    p = params
    s, cone = p.rod_spacing, (-p.cone, p.cone)
    urdf = UrdfBuilder(name, MATERIALS)
    urdf.link("base", *three_limb.base_plate("frame", p.R + sizes.plate_overhang, sizes))
    for i, alpha in zip(LIMBS, p.alpha, strict=True):
        urdf.joint(f"limb_{i}_joint", "fixed", "base", f"limb_{i}", rpy=(0, 0, alpha))
        urdf.link(f"limb_{i}")
        urdf.joint(f"actuator_{i}", "revolute", f"limb_{i}", f"upper_arm_{i}", xyz=(p.R, 0, 0), axis=(0, 1, 0),
                   limit=p.theta_limits)
        urdf.link(f"upper_arm_{i}", visual("box", "arm", xyz=(0.5 * p.la, 0, 0), size=(p.la, 0.03, 0.03)),
                  visual("cylinder", "arm", xyz=(p.la, 0, 0), rpy=(0.5 * math.pi, 0, 0), radius=0.008, length=s + 0.03),
                  *capsule((0, 0, 0), (p.la, 0, 0), sizes.arm_radius))
        for k in RODS:
            three_limb.add_rod(urdf, i, k, f"upper_arm_{i}", ("elbow", (p.la, rod_offset(k, s), 0), (0, p.elbow_socket, 0)),
                               ("u_psi", (0, 0, 0), cone), cone, p.lb, sizes.rod_radius)
    three_limb.add_platform(urdf, _platform_mount(p), p.alpha, p.r, lambda k: rod_offset(k, s),
                            visual("cylinder", "platform", radius=p.r + sizes.platform_overhang, length=0.01),
                            three_limb.platform_sphere(p.r + sizes.platform_overhang))
    for i in LIMBS:
        urdf.joint(f"psocket_{i}_joint", "fixed", f"pmount_{i}", f"psocket_{i}", xyz=(p.r, 0, 0),
                   rpy=(0, p.platform_socket, 0))
        urdf.link(f"psocket_{i}")
    return urdf.text(f"""{MECHANISM} parallel robot (Clavel).
Generated by {command(p)} (kinematics.mechanisms.delta.urdf); do not edit.
Loop closures and actuated joints: the .loops.yaml sidecar.
R={num(p.R)} r={num(p.r)} la={num(p.la)} lb={num(p.lb)} m, cone {num(p.cone)} rad, rod spacing {num(p.rod_spacing)} m.
Collision shapes (m): {' '.join(f'{k}={num(v)}' for k, v in sizes.as_dict().items())}.""")


def reference_pose(params: DeltaParams) -> tuple[np.ndarray, str]:
    """A platform position on the z axis where the robot is assembled in mode '---' with every
    limit respected (mid-way along the valid stretch of the axis), else merely assembled."""
    return three_limb.axis_reference(ik, params, 2 * (params.R + params.la + params.lb), 8001)


def joint_values_at(params: DeltaParams, p: np.ndarray, mode: str = "---") -> dict[str, float]:
    """Every joint value of the URDF tree with the platform at `p` [m] in working mode `mode`
    (loops closed), from the closed forms. Raises InvalidInputError where a limb cannot reach."""
    theta, n = three_limb.mode_solution(limb_ik, params, p, mode)
    psi, phi = passive_angles(params, theta, n)
    eps = theta[0] + params.elbow_socket + psi[0]  # rod (1, 1)'s angle in limb 1's plane
    return three_limb.tree_values("actuator", theta, "u_psi", psi, phi, float(math.remainder(math.pi / 2 - eps, 2 * math.pi)))


def configurations_at(params: DeltaParams, model: Any, points: np.ndarray, mode: str) -> np.ndarray:
    """Pinocchio configurations (N, nq) of this URDF's `model` with the platform at `points`
    (N, 3) [m] in working mode `mode` (loops closed; `joint_values_at` at many points, NaN rows
    where a limb cannot reach)."""
    theta, n = three_limb.mode_solutions(limb_ik, params, points, mode)
    psi, phi = passive_angles(params, theta, n)
    half = 0.5 * math.pi - (theta[:, 0] + params.elbow_socket + psi[:, 0])
    s_2 = half - 2 * math.pi * np.round(half / (2 * math.pi))  # math.remainder's range, [-pi, pi]
    return three_limb.tree_arrays(model, three_limb.tree_value_arrays("actuator", theta, "u_psi", psi, phi, s_2))


def reference_configuration(params: DeltaParams) -> dict[str, float]:
    """Joint values of an assembled configuration (loops closed), for the sidecar."""
    return joint_values_at(params, *reference_pose(params))


def sidecar_text(params: DeltaParams, urdf_name: str, sizes: CollisionSizes = SIZES) -> str:
    """The loop-closure sidecar (YAML) of the URDF written by `urdf_text`, with its `collisions`
    block (the collision sizes, no disabled pair)."""
    return three_limb.sidecar_text(MECHANISM, command(params), urdf_name, "actuator",
                                   reference_configuration(params), three_limb.collisions_block(sizes),
                                   [three_limb.COLLISIONS_NOTE])


write = three_limb.writer(urdf_text, sidecar_text)


# -- reader -------------------------------------------------------------------------------------
def read_params(urdf_path: str | os.PathLike[str], robot: str | None = None) -> DeltaParams:
    """Read a Delta design back from its URDF (the layout `urdf_text` writes); raises
    UnsupportedRobotError naming the missing or inconsistent joint when it has another layout."""
    layout = LayoutReader(urdf_path, robot, MECHANISM, "limb_i_joint, actuator_i, elbow_i_k_joint, u_psi_i_k, "
                          "u_phi_i_k, tip_i_k_joint, s_1..s_3, pmount_i_joint, anchor_i_k_joint, psocket_i_joint")
    alpha, (need, fail) = layout.limb_angles(), (layout.need, layout.fail)
    R, th_lim, spacing, sigma, cones, la, lb, r, kappa = ([] for _ in range(9))
    for i in LIMBS:
        act, xyz, rpy = layout.placed(f"actuator_{i}", "revolute")
        if xyz[1:] != (0, 0) or rpy != (0, 0, 0) or axis_of(act) != (0, 1, 0):
            raise fail(f"joint 'actuator_{i}' must sit at (R, 0, 0) with axis y")
        R.append(xyz[0])
        th_lim.append(limit_of(act))
        for k in RODS:
            xyz, rpy = origin_of(need(f"elbow_{i}_{k}_joint", "fixed"))
            if xyz[2] != 0 or rpy[0] != 0 or rpy[2] != 0:
                raise fail(f"joint 'elbow_{i}_{k}_joint' must be (la, -/+s/2, 0), rpy (0, sigma, 0)")
            la.append(xyz[0])
            spacing.append(2 * xyz[1] if k == 2 else -2 * xyz[1])
            sigma.append(rpy[1])
            for name, ax in ((f"u_psi_{i}_{k}", (0, 1, 0)), (f"u_phi_{i}_{k}", (0, 0, 1))):
                u = need(name, "revolute")
                lo, hi = limit_of(u)
                if origin_of(u) != ((0, 0, 0), (0, 0, 0)) or axis_of(u) != ax or lo != -hi:
                    raise fail(f"joint {name!r} must have no offset, axis {ax} and limits [-cone, cone]")
                cones.append(hi)
            lb.append(layout.tip_length(i, k, "lb"))
            xyz, rpy = origin_of(need(f"anchor_{i}_{k}_joint", "fixed"))
            if xyz[1] != rod_offset(k, spacing[-1]) or xyz[2] != 0 or rpy != (0, 0, 0):
                raise fail(f"anchor_{i}_{k} must sit at (r, y_k, 0) on the same side as rod {i}_{k}")
            r.append(xyz[0])
        xyz, rpy = origin_of(need(f"psocket_{i}_joint", "fixed"))
        if rpy[0] != 0 or rpy[2] != 0:
            raise fail(f"joint 'psocket_{i}_joint' must be rpy (0, kappa, 0)")
        kappa.append(rpy[1])
    layout.check_platform(alpha)
    same = layout.same
    return DeltaParams(
        R=same("R", R), r=same("r", r), la=same("la", la), lb=same("lb", lb), alpha=tuple(alpha),  # type: ignore[arg-type]
        theta_limits=same("actuator limits", th_lim), cone=same("cone", cones), elbow_socket=same("elbow socket", sigma),
        platform_socket=same("platform socket", kappa), rod_spacing=same("rod spacing", spacing),
    )
