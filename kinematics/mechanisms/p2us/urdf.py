"""Write and read the URDF + loop sidecar of a 3-[P2(US)] design.

Tree (limb i = 1..3, rod k = 1, 2; see docs/p2us.md for the figure):

    base
     +- limb_i_joint     fixed      rpy (0, 0, alpha_i)                    frame x = e_i
         +- slider_i     prismatic  xyz (b, 0, 0) rpy (0, beta, pi), axis x   x = w_i (inward, down)
             +- mount_i_k_joint  fixed  xyz (0, -/+ s/2, 0) rpy (0, -beta, 0)  x = -e_i, y = -t_i
                 +- u_theta_i_k   revolute  rpy (0, theta_zero, 0), axis y  (rod elevation)
                     +- u_phi_i_k     revolute  axis z                      (out of plane)
                         +- tip_i_k_joint  fixed  xyz (L, 0, 0)             link tip_i_k (sphere centre)
    tip_1_1 -> s_1 (z) -> s_2 (y) -> s_3 (x) -> platform_joint (fixed) -> platform
    platform -> pmount_i_joint (rpy (0, 0, alpha_i)) -> anchor_i_k_joint (xyz (d, +/- s/2, 0))

(Fixed joints carry a `_joint` suffix: Pinocchio makes a frame for each joint and each link.)

The platform hangs from rod (1, 1) through a spherical joint modelled as three revolute joints
(so the tree is the physical mechanism and every joint is a real one); their axes are ordered and
the fixed `platform_mount` rotation chosen so that the gimbal lock (s_2 = +/-90 deg) falls at
theta = mid-range -/+ 90 deg, outside the universal joint's range. The other five rod tips are
closed onto their anchors by point constraints in the sidecar. Every design number appears
verbatim in exactly one place, written as the shortest text of the same float, so generate ->
read round-trips exactly. The shared parts of the tree, the sidecar and the writing are
`kinematics.mechanisms.three_limb.urdf`'s.

The sidecar's `u_joint_angles` block records what the universal-joint limits bound
(`parallel.THETA_CONVENTIONS`, `PHI_CONVENTIONS`). Under theta "elevation" the theta range is the
u_theta joint's URDF limit; under "rod-rail" (the angle between rod and rail, a function of both
joint coordinates) the URDF joint is unlimited (+/-pi) and the range is written in the sidecar.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from kinematics.errors import ModelFileError, UnsupportedRobotError
from kinematics.mechanisms.p2us.closed_form import P2USParams, limb_ik, passive_angles
from kinematics.mechanisms.three_limb import urdf as three_limb
from kinematics.mechanisms.three_limb.reader import LayoutReader
from kinematics.mechanisms.three_limb.urdf import LIMBS as LIMBS
from kinematics.mechanisms.three_limb.urdf import RODS as RODS
from kinematics.mechanisms.three_limb.urdf import SPHERICAL as SPHERICAL
from kinematics.mechanisms.three_limb.urdf import CollisionSizes
from kinematics.model.loops import sidecar_for
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

MECHANISM = "3-[P2(US)]"


DESIGNS: dict[str, P2USParams] = {
    "table2": P2USParams(),
    "results": P2USParams(
        b=0.478, L=0.400, alpha=(math.radians(-90), math.radians(30), math.radians(150)),
        theta_convention="rod-rail",
    ),
}
"""Presets of the generator (`kinematics urdf p2us --design NAME`), the two built-in designs:

* "table2" (built-in `p2us`): paper B's published dimensions (Table 2) and eq. 30's limits, with
  theta read as the rod's elevation;
* "results" (built-in `p2us-results`): the geometry behind paper B's computed results (Table 3,
  Fig. 8, the workspace volume), reconstructed in docs/paper-b-reproduction.md: b - d = 450 mm
  (d = 28 mm kept, so b = 478 mm), L = 400 mm (Table 1's rods), limbs at -90, 30, 150 deg (eq. 24's
  directions), theta read as the rod-rail angle; beta, strokes and limits as published.
"""

SIZES = CollisionSizes()
"""Default collision sizes (`kinematics urdf p2us --rod-radius ...`): rods 6 mm, rails 10 mm in
radius, a 20 mm base plate 30 mm beyond b, the platform's sphere 20 mm beyond d."""

BUILTIN_DESIGNS = {"p2us": "table2", "p2us-results": "results"}
"""Built-in robot name -> the preset its committed URDF is generated from."""


def theta_centre(params: P2USParams) -> float:
    """The u_theta coordinate where the platform's spherical joint is farthest from gimbal lock:
    the middle of the rods' allowed swing (`P2USParams.theta_joint_centre`)."""
    return params.theta_joint_centre


def theta_joint_limits(params: P2USParams) -> tuple[float, float]:
    """The u_theta joint's URDF limits: theta_limits when they bound that coordinate
    ("elevation"), else unlimited (-pi, pi) (the sidecar holds the rod-rail range)."""
    return params.theta_limits if params.theta_convention == "elevation" else (-math.pi, math.pi)


def _platform_mount(params: P2USParams) -> tuple[np.ndarray, np.ndarray]:
    """Fixed placement (translation, rotation) from the s_3 body to the platform frame."""
    psi = params.theta_zero + theta_centre(params)
    R_s3 = rot_z(params.alpha[0] + math.pi) @ rot_y(psi)  # world orientation of the s_3 body
    anchor = params.d * params.e[0] + 0.5 * params.rod_spacing * params.t[0]  # anchor_1_1, platform axes
    return three_limb.platform_mount(R_s3, anchor)


MATERIALS = {"frame": "0.6 0.6 0.65 1", "rail": "0.3 0.3 0.35 1", "carriage": "0.95 0.55 0.1 1",
             "rod": "0.2 0.45 0.85 1", **three_limb.JOINT_MATERIAL, "platform": "0.85 0.2 0.2 1"}


def command(params: P2USParams) -> str:
    """How this design is written, for the files' headers: `kinematics urdf p2us` with the preset
    it is (`DESIGNS`) or "design flags" (no double hyphen: XML comments cannot hold one)."""
    for preset, design in DESIGNS.items():
        if params == design:
            return f"`kinematics urdf p2us`, design preset {preset}"
    return "`kinematics urdf p2us` with design flags"


def urdf_text(params: P2USParams, name: str = "p2us", sizes: CollisionSizes = SIZES) -> str:
    """The URDF of a 3-[P2(US)] design (`xml.etree.ElementTree`, indented), with collision
    shapes of `sizes` (`three_limb.urdf.CollisionSizes`): base plate, rails, rods, platform."""
    p = params
    L, s = p.L, p.rod_spacing
    rail = p.stroke[1] + 0.05
    urdf = UrdfBuilder(name, MATERIALS)
    urdf.link("base", *three_limb.base_plate("frame", p.b + sizes.plate_overhang, sizes))
    for i, alpha in zip(LIMBS, p.alpha, strict=True):
        urdf.joint(f"limb_{i}_joint", "fixed", "base", f"limb_{i}", rpy=(0, 0, alpha))
        c, sn = math.cos(p.beta), math.sin(p.beta)
        # the rail's bar runs from (b, 0, 0.02) inward and down along the carriage's path
        urdf.link(f"limb_{i}", visual("box", "rail", xyz=(p.b - 0.5 * rail * c, 0, -0.5 * rail * sn + 0.02),
                                      rpy=(0, p.beta, math.pi), size=(rail, 0.03, 0.02)),
                  *capsule((p.b, 0, 0.02), (p.b - rail * c, 0, -rail * sn + 0.02), sizes.arm_radius))
        urdf.joint(f"slider_{i}", "prismatic", f"limb_{i}", f"carriage_{i}", xyz=(p.b, 0, 0),
                   rpy=(0, p.beta, math.pi), axis=(1, 0, 0), limit=p.stroke)
        urdf.link(f"carriage_{i}", visual("box", "carriage", size=(0.06, s + 0.04, 0.03)))
        for k in RODS:
            # the mount frame's y is -t_i: rod 1 sits on the +t_i side
            three_limb.add_rod(urdf, i, k, f"carriage_{i}", ("mount", (0, three_limb.rod_offset(k, s), 0), (0, -p.beta, 0)),
                               ("u_theta", (0, p.theta_zero, 0), theta_joint_limits(p)), p.phi_limits, L,
                               sizes.rod_radius)
    three_limb.add_platform(urdf, _platform_mount(p), p.alpha, p.d, lambda k: -three_limb.rod_offset(k, s),
                            visual("cylinder", "platform", radius=p.d + sizes.platform_overhang, length=0.01),
                            visual("sphere", "joint", radius=0.008), three_limb.platform_sphere(p.d + sizes.platform_overhang))
    return urdf.text(f"""{MECHANISM} translational parallel robot (paper B, Mazare et al. 2016).
Generated by {command(p)} (kinematics.mechanisms.p2us.urdf); do not edit.
Loop closures and actuated joints: the .loops.yaml sidecar.
b={num(p.b)} d={num(p.d)} L={num(p.L)} m, beta={num(p.beta)} rad, rod spacing {num(p.rod_spacing)} m.
Collision shapes (m): {' '.join(f'{k}={num(v)}' for k, v in sizes.as_dict().items())}.""")


def reference_pose(params: P2USParams) -> tuple[np.ndarray, str]:
    """A platform position on the z axis where the robot is assembled in mode '---' with every
    limit respected (mid-way along the valid stretch of the axis), else merely assembled."""
    from kinematics.mechanisms.p2us.closed_form import ik

    return three_limb.axis_reference(ik, params, 3 * (params.b + params.L), 6001)


def joint_values_at(params: P2USParams, p: np.ndarray, mode: str = "---") -> dict[str, float]:
    """Every joint value of the URDF tree with the platform at `p` [m] in working mode `mode`
    (loops closed), from the closed forms. Raises InvalidInputError where a limb cannot reach."""
    q, n = three_limb.mode_solution(limb_ik, params, p, mode)
    theta, phi = passive_angles(params, n)
    return three_limb.tree_values("slider", q, "u_theta", theta, phi, theta_centre(params) - float(theta[0]))


def configurations_at(params: P2USParams, model: Any, points: np.ndarray, mode: str) -> np.ndarray:
    """Pinocchio configurations (N, nq) of this URDF's `model` with the platform at `points`
    (N, 3) [m] in working mode `mode` (loops closed; `joint_values_at` at many points, NaN rows
    where a limb cannot reach), compiled (`kinematics.mechanisms.p2us.configurations`)."""
    from kinematics.mechanisms.p2us.configurations import configurations

    return configurations(params, model, points, mode)


def reference_configuration(params: P2USParams) -> dict[str, float]:
    """Joint values of an assembled configuration (loops closed), for the sidecar."""
    return joint_values_at(params, *reference_pose(params))


def sidecar_text(params: P2USParams, urdf_name: str, sizes: CollisionSizes = SIZES) -> str:
    """The loop-closure sidecar (YAML) of the URDF written by `urdf_text`; its `u_joint_angles`
    block says what the universal-joint limits bound (closed_form.THETA/PHI_CONVENTIONS), its
    `collisions` block the collision sizes and disabled pairs."""
    angles: dict[str, object] = {"theta": params.theta_convention}
    if params.theta_convention != "elevation":
        angles["theta_limits"] = [float(x) for x in params.theta_limits]  # rad
    angles["phi"] = params.phi_convention
    return three_limb.sidecar_text(MECHANISM, command(params), urdf_name, "slider", reference_configuration(params),
                                   {"u_joint_angles": angles, **three_limb.collisions_block(sizes)},
                                   ["u_joint_angles: what the universal-joint limits bound (theta_limits in rad).",
                                    three_limb.COLLISIONS_NOTE])


def sidecar_path(urdf_path: str | os.PathLike[str]) -> Path:
    """`robot.urdf` -> `robot.loops.yaml`."""
    return sidecar_for(Path(urdf_path))


write = three_limb.writer(urdf_text, sidecar_text)


# -- reader -------------------------------------------------------------------------------------
def read_params(urdf_path: str | os.PathLike[str], robot: str | None = None) -> P2USParams:
    """Read a 3-[P2(US)] design back from its URDF (the layout `urdf_text` writes) and the
    `u_joint_angles` block of its sidecar (`read_conventions`); UnsupportedRobotError names the
    missing or inconsistent joint when the URDF does not have that layout."""
    layout = LayoutReader(urdf_path, robot, MECHANISM, _layout_hint())
    need, fail = layout.need, layout.fail
    alpha = layout.limb_angles()
    b, beta, stroke, spacing, theta0, th_lim, ph_lim, L, d = ([] for _ in range(9))
    for i in LIMBS:
        slider, xyz, rpy = layout.placed(f"slider_{i}", "prismatic")
        if xyz[1:] != (0, 0) or rpy[0] != 0 or rpy[2] != math.pi or axis_of(slider) != (1, 0, 0):
            raise fail(f"joint 'slider_{i}' must sit at (b, 0, 0), rpy (0, beta, pi), axis x")
        b.append(xyz[0])
        beta.append(rpy[1])
        stroke.append(limit_of(slider))
        for k in RODS:
            xyz, rpy = origin_of(need(f"mount_{i}_{k}_joint", "fixed"))
            if xyz[0] != 0 or xyz[2] != 0 or rpy != (0, -beta[-1], 0):
                raise fail(f"joint 'mount_{i}_{k}_joint' must be (0, -/+s/2, 0), rpy (0, -beta, 0)")
            spacing.append(2 * xyz[1] if k == 2 else -2 * xyz[1])
            ut = need(f"u_theta_{i}_{k}", "revolute")
            xyz, rpy = origin_of(ut)
            if xyz != (0, 0, 0) or rpy[0] != 0 or rpy[2] != 0 or axis_of(ut) != (0, 1, 0):
                raise fail(f"joint 'u_theta_{i}_{k}' must be rpy (0, theta_zero, 0), axis y")
            theta0.append(rpy[1])
            th_lim.append(limit_of(ut))
            up = need(f"u_phi_{i}_{k}", "revolute")
            if origin_of(up) != ((0, 0, 0), (0, 0, 0)) or axis_of(up) != (0, 0, 1):
                raise fail(f"joint 'u_phi_{i}_{k}' must have no offset and axis z")
            ph_lim.append(limit_of(up))
            L.append(layout.tip_length(i, k, "L"))
            xyz, _ = origin_of(need(f"anchor_{i}_{k}_joint", "fixed"))
            d.append(xyz[0])
            if xyz[1] != (0.5 if k == 1 else -0.5) * spacing[-1]:
                raise fail(f"anchor_{i}_{k} is not on the same side as rod {i}_{k}'s joint")
    layout.check_platform(alpha)
    conventions = read_conventions(urdf_path, layout.who)
    if "theta_limits" in conventions:
        th_lim = [conventions.pop("theta_limits")]
    same = layout.same
    return P2USParams(
        b=same("b", b), d=same("d", d), L=same("L", L), beta=same("beta", beta), alpha=tuple(alpha),  # type: ignore[arg-type]
        stroke=same("stroke", stroke), theta_limits=same("theta limits", th_lim), phi_limits=same("phi limits", ph_lim),
        theta_zero=same("theta_zero", theta0), rod_spacing=same("rod spacing", spacing), **conventions,
    )


def read_conventions(urdf_path: str | os.PathLike[str], robot: str) -> dict:
    """The `u_joint_angles` block of the sidecar beside `urdf_path` as P2USParams fields
    (theta_convention, phi_convention and, for a non-elevation theta, theta_limits); empty (the
    defaults: elevation, tangential) when the sidecar or the block is absent."""
    import yaml

    side = sidecar_path(urdf_path)
    if not side.exists():
        return {}
    try:
        raw = yaml.safe_load(side.read_text())
    except (yaml.YAMLError, OSError) as exc:
        raise ModelFileError(side, f"cannot read the loop sidecar ({exc})") from None
    block = raw.get("u_joint_angles") if isinstance(raw, dict) else None
    if block is None:
        return {}
    if not isinstance(block, dict):
        raise ModelFileError(side, "u_joint_angles must be a mapping")
    out: dict = {}
    if "theta" in block:
        out["theta_convention"] = str(block["theta"])
    if "phi" in block:
        out["phi_convention"] = str(block["phi"])
    theta = out.get("theta_convention", "elevation")
    if theta != "elevation":
        lim = block.get("theta_limits")
        if not (isinstance(lim, list) and len(lim) == 2 and all(isinstance(x, (int, float)) for x in lim)):
            raise UnsupportedRobotError(robot, f"u_joint_angles: theta {theta!r} needs theta_limits: [lower, upper] [rad]")
        out["theta_limits"] = (float(lim[0]), float(lim[1]))
    elif "theta_limits" in block:
        raise UnsupportedRobotError(robot, "u_joint_angles: with theta 'elevation' the range is the u_theta joint's URDF limit")
    return out


def _layout_hint() -> str:
    return ("expected joints limb_i_joint, slider_i, mount_i_k_joint, u_theta_i_k, u_phi_i_k, tip_i_k_joint, "
            "s_1..s_3, pmount_i_joint, anchor_i_k_joint")
