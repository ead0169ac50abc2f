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
verbatim in exactly one place, written with 17 significant digits, so generate -> read
round-trips exactly.

The sidecar's `u_joint_angles` block records what the universal-joint limits bound
(`parallel.THETA_CONVENTIONS`, `PHI_CONVENTIONS`). Under theta "elevation" the theta range is the
u_theta joint's URDF limit; under "rod-rail" (the angle between rod and rail, a function of both
joint coordinates) the URDF joint is unlimited (+/-pi) and the range is written in the sidecar.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from kinematics.errors import InvalidInputError, ModelFileError, UnsupportedRobotError
from kinematics.mechanisms.p2us.closed_form import MODES as MODES_BY_INDEX
from kinematics.mechanisms.p2us.closed_form import P2USParams, limb_ik, passive_angles
from kinematics.model.urdf_xml import axis_of as _axis
from kinematics.model.urdf_xml import axis_reference
from kinematics.model.urdf_xml import fmt17 as _f
from kinematics.model.urdf_xml import joint as _joint
from kinematics.model.urdf_xml import limit_of as _limit
from kinematics.model.urdf_xml import link as _link
from kinematics.model.urdf_xml import origin_of as _origin
from kinematics.model.urdf_xml import rot_y as _rot_y
from kinematics.model.urdf_xml import rot_z as _rot_z
from kinematics.model.urdf_xml import rpy_of as _rpy
from kinematics.model.urdf_xml import vec as _v
from kinematics.model.urdf_xml import visual as _visual

MECHANISM = "3-[P2(US)]"
LIMBS = (1, 2, 3)
RODS = (1, 2)
SPHERICAL = ("s_1", "s_2", "s_3")


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

BUILTIN_DESIGNS = {"p2us": "table2", "p2us-results": "results"}
"""Built-in robot name -> the preset its committed URDF is generated from."""


def _rod_offset(k: int, s: float) -> float:
    """Lateral offset of rod k along the mount frame's y = -t_i: rod 1 sits on the +t_i side."""
    return -0.5 * s if k == 1 else 0.5 * s


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
    R_s3 = _rot_z(params.alpha[0] + math.pi) @ _rot_y(psi)  # world orientation of the s_3 body
    e, t = params.e[0], params.t[0]
    anchor = params.d * e + 0.5 * params.rod_spacing * t  # anchor_1_1 in platform (= world) axes
    return R_s3.T @ (-anchor), R_s3.T


def urdf_text(params: P2USParams, name: str = "p2us") -> str:
    """The URDF of a 3-[P2(US)] design."""
    p = params
    L, s = p.L, p.rod_spacing
    rail = p.stroke[1] + 0.05
    out = [
        '<?xml version="1.0"?>',
        f"<!-- {MECHANISM} translational parallel robot (paper B, Mazare et al. 2016), generated by",
        "     `kinematics urdf p2us`. Loop closures and actuated joints: the .loops.yaml sidecar.",
        f"     b={_f(p.b)} d={_f(p.d)} L={_f(p.L)} beta={_f(p.beta)} rad, rod spacing {_f(p.rod_spacing)} m. -->",
        f'<robot name="{name}">',
        '  <material name="frame"><color rgba="0.6 0.6 0.65 1"/></material>',
        '  <material name="rail"><color rgba="0.3 0.3 0.35 1"/></material>',
        '  <material name="carriage"><color rgba="0.95 0.55 0.1 1"/></material>',
        '  <material name="rod"><color rgba="0.2 0.45 0.85 1"/></material>',
        '  <material name="joint"><color rgba="0.15 0.15 0.15 1"/></material>',
        '  <material name="platform"><color rgba="0.85 0.2 0.2 1"/></material>',
        _link("base", _visual(f'<cylinder radius="{_f(p.b + 0.03)}" length="0.02"/>', "frame", xyz=(0, 0, 0.03))),
    ]
    for i, alpha in zip(LIMBS, p.alpha, strict=True):
        out.append(_joint(f"limb_{i}_joint", "fixed", "base", f"limb_{i}", rpy=(0, 0, alpha)))
        c, sn = math.cos(p.beta), math.sin(p.beta)
        out.append(_link(f"limb_{i}", _visual(
            f'<box size="{_v(rail, 0.03, 0.02)}"/>', "rail",
            xyz=(p.b - 0.5 * rail * c, 0, -0.5 * rail * sn + 0.02), rpy=(0, p.beta, math.pi))))
        out.append(_joint(f"slider_{i}", "prismatic", f"limb_{i}", f"carriage_{i}", xyz=(p.b, 0, 0),
                          rpy=(0, p.beta, math.pi), axis=(1, 0, 0), limit=p.stroke))
        out.append(_link(f"carriage_{i}", _visual(f'<box size="{_v(0.06, s + 0.04, 0.03)}"/>', "carriage")))
        for k in RODS:
            y = _rod_offset(k, s)
            out.append(_joint(f"mount_{i}_{k}_joint", "fixed", f"carriage_{i}", f"mount_{i}_{k}", xyz=(0, y, 0),
                              rpy=(0, -p.beta, 0)))
            out.append(_link(f"mount_{i}_{k}", _visual('<sphere radius="0.012"/>', "joint")))
            out.append(_joint(f"u_theta_{i}_{k}", "revolute", f"mount_{i}_{k}", f"ucross_{i}_{k}",
                              rpy=(0, p.theta_zero, 0), axis=(0, 1, 0), limit=theta_joint_limits(p)))
            out.append(_link(f"ucross_{i}_{k}"))
            out.append(_joint(f"u_phi_{i}_{k}", "revolute", f"ucross_{i}_{k}", f"rod_{i}_{k}",
                              axis=(0, 0, 1), limit=p.phi_limits))
            out.append(_link(f"rod_{i}_{k}", _visual(f'<cylinder radius="0.006" length="{_f(L)}"/>', "rod",
                                                     xyz=(0.5 * L, 0, 0), rpy=(0, 0.5 * math.pi, 0))))
            out.append(_joint(f"tip_{i}_{k}_joint", "fixed", f"rod_{i}_{k}", f"tip_{i}_{k}", xyz=(L, 0, 0)))
            out.append(_link(f"tip_{i}_{k}", _visual('<sphere radius="0.01"/>', "joint")))
    chain = ["tip_1_1", "sphere_a", "sphere_b", "sphere_c"]
    for jname, parent, child, axis in zip(SPHERICAL, chain[:-1], chain[1:], ((0, 0, 1), (0, 1, 0), (1, 0, 0)), strict=True):
        out.append(_joint(jname, "revolute", parent, child, axis=axis, limit=(-math.pi, math.pi)))
        out.append(_link(child))
    xyz, R = _platform_mount(p)
    out.append(_joint("platform_joint", "fixed", "sphere_c", "platform", xyz=tuple(xyz), rpy=_rpy(R)))
    out.append(_link("platform", _visual(f'<cylinder radius="{_f(p.d + 0.02)}" length="0.01"/>', "platform"),
                     _visual('<sphere radius="0.008"/>', "joint")))
    for i, alpha in zip(LIMBS, p.alpha, strict=True):
        out.append(_joint(f"pmount_{i}_joint", "fixed", "platform", f"pmount_{i}", rpy=(0, 0, alpha)))
        out.append(_link(f"pmount_{i}"))
        for k in RODS:
            out.append(_joint(f"anchor_{i}_{k}_joint", "fixed", f"pmount_{i}", f"anchor_{i}_{k}",
                              xyz=(p.d, -_rod_offset(k, s), 0)))
            out.append(_link(f"anchor_{i}_{k}"))
    out.append("</robot>")
    return "\n".join(out) + "\n"


def reference_pose(params: P2USParams) -> tuple[np.ndarray, str]:
    """A platform position on the z axis where the robot is assembled in mode '---' with every
    limit respected (mid-way along the valid stretch of the axis), else merely assembled."""
    from kinematics.mechanisms.p2us.closed_form import ik, mode_index

    return axis_reference(ik, params, 3 * (params.b + params.L), 6001, mode_index("---"))


def joint_values_at(params: P2USParams, p: np.ndarray, mode: str = "---") -> dict[str, float]:
    """Every joint value of the URDF tree with the platform at `p` [m] in working mode `mode`
    (loops closed), from the closed forms. Raises InvalidInputError where a limb cannot reach."""
    from kinematics.mechanisms.p2us.closed_form import mode_index

    m = mode_index(mode)
    pos = np.asarray(p, dtype=float).reshape(3)
    limbs = limb_ik(params, pos)
    if not limbs.reach.all():
        bad = [str(i + 1) for i in range(3) if not limbs.reach[i]]
        raise InvalidInputError("position", f"limb(s) {', '.join(bad)} cannot reach {pos.tolist()}")
    roots = [0 if c == "+" else 1 for c in MODES_BY_INDEX[m]]
    q = limbs.q[np.arange(3), roots]
    theta, phi = passive_angles(params, limbs.n[np.arange(3), roots])
    values: dict[str, float] = {}
    for i in LIMBS:
        values[f"slider_{i}"] = float(q[i - 1])
        for k in RODS:
            values[f"u_theta_{i}_{k}"] = float(theta[i - 1])
            values[f"u_phi_{i}_{k}"] = float(phi[i - 1])
    values["s_1"] = -values["u_phi_1_1"]
    values["s_2"] = theta_centre(params) - values["u_theta_1_1"]
    values["s_3"] = 0.0
    return values


def reference_configuration(params: P2USParams) -> dict[str, float]:
    """Joint values of an assembled configuration (loops closed), for the sidecar."""
    pos, mode = reference_pose(params)
    return joint_values_at(params, pos, mode)


def sidecar_text(params: P2USParams, urdf_name: str) -> str:
    """The loop-closure sidecar (YAML) of the URDF written by `urdf_text`."""
    ref = reference_configuration(params)
    lines = [
        f"# Loop closures of {urdf_name} ({MECHANISM}). Generated by `kinematics urdf p2us`.",
        "# closures: each pair of frames must coincide (a 3D point constraint = a spherical joint).",
        "# reference: an assembled configuration (loops closed), the closed-loop solver's start.",
        "format: kinematics-loops/1",
        f"mechanism: {MECHANISM}",
        f"urdf: {urdf_name}",
        "end_effector: platform",
        "actuated: [" + ", ".join(f"slider_{i}" for i in LIMBS) + "]",
        "u_joint_angles:  # what the universal-joint limits bound (kinematics.mechanisms.p2us.closed_form: THETA/PHI_CONVENTIONS)",
        f"  theta: {params.theta_convention}",
    ]
    if params.theta_convention != "elevation":
        lines.append(f"  theta_limits: [{_f(params.theta_limits[0])}, {_f(params.theta_limits[1])}]  # rad")
    lines += [
        f"  phi: {params.phi_convention}",
        "closures:",
    ]
    for i in LIMBS:
        for k in RODS:
            if (i, k) == (1, 1):
                continue  # rod (1, 1) carries the platform in the tree
            lines.append(f"  - {{name: S_{i}_{k}, type: point, frame1: tip_{i}_{k}, frame2: anchor_{i}_{k}}}")
    lines.append("reference:")
    lines += [f"  {name}: {_f(value)}" for name, value in ref.items()]
    return "\n".join(lines) + "\n"


def sidecar_path(urdf_path: str | os.PathLike[str]) -> Path:
    """`robot.urdf` -> `robot.loops.yaml`."""
    p = Path(urdf_path)
    return p.with_name(p.stem + ".loops.yaml")


def write(params: P2USParams, path: str | os.PathLike[str], name: str | None = None) -> tuple[Path, Path]:
    """Write the URDF to `path` and its sidecar beside it; returns both paths.

    Both are written as one (`files.write_atomic_files`): on any failure neither file is
    half-written, and files already there are left as they were.
    """
    urdf_path = Path(path)
    side = sidecar_path(urdf_path)
    robot_name = name or urdf_path.stem
    urdf = urdf_text(params, robot_name)
    loops = sidecar_text(params, urdf_path.name)
    if not urdf_path.parent.is_dir():
        raise ModelFileError(urdf_path.parent, "output directory does not exist")
    from kinematics.files import write_atomic_files

    write_atomic_files([(str(urdf_path), urdf), (str(side), loops)], "output")
    return urdf_path, side


# -- reader -------------------------------------------------------------------------------------
def read_params(urdf_path: str | os.PathLike[str], robot: str | None = None) -> P2USParams:
    """Read a 3-[P2(US)] design back from its URDF (the layout `urdf_text` writes).

    Raises:
        UnsupportedRobotError: naming the missing or inconsistent joint when the URDF does not
            have that layout.
    """
    from kinematics.model.robot import check_urdf_file

    root = check_urdf_file(urdf_path)
    who = robot or Path(urdf_path).stem
    joints = {j.get("name"): j for j in root.findall("joint")}

    def need(name: str, kind: str) -> ET.Element:
        j = joints.get(name)
        if j is None:
            raise UnsupportedRobotError(who, f"not a {MECHANISM}: missing joint {name!r} ({_layout_hint()})")
        if j.get("type") != kind:
            raise UnsupportedRobotError(who, f"not a {MECHANISM}: joint {name!r} is {j.get('type')}, expected {kind}")
        return j

    def same(what: str, values: list) -> object:
        if any(v != values[0] for v in values[1:]):
            raise UnsupportedRobotError(who, f"the closed forms need identical limbs/rods, but {what} differs: {values}")
        return values[0]

    alpha, b, beta, stroke, spacing, theta0, th_lim, ph_lim, L, d = ([] for _ in range(10))
    for i in LIMBS:
        xyz, rpy = _origin(need(f"limb_{i}_joint", "fixed"))
        if xyz != (0, 0, 0) or rpy[:2] != (0, 0):
            raise UnsupportedRobotError(who, f"joint 'limb_{i}_joint' must be a pure rotation about z")
        alpha.append(rpy[2])
        slider = need(f"slider_{i}", "prismatic")
        xyz, rpy = _origin(slider)
        if xyz[1:] != (0, 0) or rpy[0] != 0 or rpy[2] != math.pi or _axis(slider) != (1, 0, 0):
            raise UnsupportedRobotError(who, f"joint 'slider_{i}' must sit at (b, 0, 0), rpy (0, beta, pi), axis x")
        b.append(xyz[0])
        beta.append(rpy[1])
        stroke.append(_limit(slider))
        for k in RODS:
            xyz, rpy = _origin(need(f"mount_{i}_{k}_joint", "fixed"))
            if xyz[0] != 0 or xyz[2] != 0 or rpy != (0, -beta[-1], 0):
                raise UnsupportedRobotError(who, f"joint 'mount_{i}_{k}_joint' must be (0, -/+s/2, 0), rpy (0, -beta, 0)")
            spacing.append(2 * xyz[1] if k == 2 else -2 * xyz[1])
            ut = need(f"u_theta_{i}_{k}", "revolute")
            xyz, rpy = _origin(ut)
            if xyz != (0, 0, 0) or rpy[0] != 0 or rpy[2] != 0 or _axis(ut) != (0, 1, 0):
                raise UnsupportedRobotError(who, f"joint 'u_theta_{i}_{k}' must be rpy (0, theta_zero, 0), axis y")
            theta0.append(rpy[1])
            th_lim.append(_limit(ut))
            up = need(f"u_phi_{i}_{k}", "revolute")
            if _origin(up) != ((0, 0, 0), (0, 0, 0)) or _axis(up) != (0, 0, 1):
                raise UnsupportedRobotError(who, f"joint 'u_phi_{i}_{k}' must have no offset and axis z")
            ph_lim.append(_limit(up))
            xyz, rpy = _origin(need(f"tip_{i}_{k}_joint", "fixed"))
            if xyz[1:] != (0, 0) or rpy != (0, 0, 0):
                raise UnsupportedRobotError(who, f"joint 'tip_{i}_{k}_joint' must be (L, 0, 0)")
            L.append(xyz[0])
            xyz, _ = _origin(need(f"anchor_{i}_{k}_joint", "fixed"))
            d.append(xyz[0])
            if xyz[1] != (0.5 if k == 1 else -0.5) * spacing[-1]:
                raise UnsupportedRobotError(who, f"anchor_{i}_{k} is not on the same side as rod {i}_{k}'s joint")
        _, rpy = _origin(need(f"pmount_{i}_joint", "fixed"))
        if rpy != (0, 0, alpha[-1]):
            raise UnsupportedRobotError(who, f"joint 'pmount_{i}_joint' must turn by alpha_{i} about z like 'limb_{i}_joint'")
    for name in SPHERICAL:
        need(name, "revolute")
    conventions = read_conventions(urdf_path, who)
    if "theta_limits" in conventions:
        th_lim = [conventions.pop("theta_limits")]
    return P2USParams(
        b=same("b", b), d=same("d", d), L=same("L", L), beta=same("beta", beta),  # type: ignore[arg-type]
        alpha=tuple(alpha), stroke=same("stroke", stroke), theta_limits=same("theta limits", th_lim),  # type: ignore[arg-type]
        phi_limits=same("phi limits", ph_lim), theta_zero=same("theta_zero", theta0),  # type: ignore[arg-type]
        rod_spacing=same("rod spacing", spacing), **conventions,  # type: ignore[arg-type]
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
