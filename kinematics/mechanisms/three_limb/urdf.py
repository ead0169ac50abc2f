"""The URDF tree and loop sidecar both three-limb families write, and writing them.

Each limb i = 1..3 carries a parallelogram of two rods k = 1, 2; a rod hangs from a fixed mount
on its actuated link through a universal joint (two revolutes, the second about z), and ends in
`tip_i_k`. The platform hangs from rod (1, 1) through a spherical joint modelled as three
revolute joints s_1 (z), s_2 (y), s_3 (x) and a fixed `platform_joint`; `anchor_i_k` on the
platform is where rod (i, k) ends. The sidecar closes the other five rods onto their anchors by
point constraints. URDFs are built with `xml.etree.ElementTree` (`model.urdf_xml.UrdfBuilder`),
sidecars with `yaml.safe_dump`; both write every number as the shortest text that reads back as
the same float, so generate -> read round-trips exactly.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinematics.errors import InvalidInputError, ModelFileError
from kinematics.mechanisms.three_limb.closed_form import mode_index
from kinematics.mechanisms.three_limb.modes import mode_roots
from kinematics.model.loops import FORMAT, sidecar_for
from kinematics.model.urdf_xml import UrdfBuilder, capsule, collision, rpy_of, visual

LIMBS = (1, 2, 3)
RODS = (1, 2)
SPHERICAL = ("s_1", "s_2", "s_3")

JOINT_MATERIAL = {"joint": "0.15 0.15 0.15 1"}
"""The dark grey of joint spheres, shared by both families' colour sets."""


@dataclass(frozen=True)
class CollisionSizes:
    """The design parameters [m] of a three-limb robot's collision shapes (and of the visuals
    drawn from the same numbers). Every shape is convex and has a closed-form distance to the
    others (`kinematics.generic.capsules`):

    * rods: capsules of radius `rod_radius` from the universal joint's centre to the ball joint's;
    * rails (3-[P2(US)]) / upper arms (Delta): capsules of radius `arm_radius` along the drawn bar;
    * base plate: a disk (cylinder) `plate_thickness` thick whose lower face lies 0.02 m above the
      base frame, `plate_overhang` wider than the actuators' circle (b or R);
    * platform: the sphere about its centre of radius d (or r) + `platform_overhang`, which holds
      the drawn disk of that radius (a conservative shape: a sphere's distances are closed-form).
    """

    rod_radius: float = 0.006
    arm_radius: float = 0.01
    plate_thickness: float = 0.02
    plate_overhang: float = 0.03
    platform_overhang: float = 0.02

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InvalidInputError(f.name, f"must be a positive length [m], got {value!r}")

    def as_dict(self) -> dict[str, float]:
        """The sizes by name [m], JSON- and YAML-ready."""
        return {f.name: float(getattr(self, f.name)) for f in dataclasses.fields(self)}

    def replace(self, **changes: float) -> CollisionSizes:
        """A copy with `changes` (validated)."""
        return dataclasses.replace(self, **changes)


PLATE_GAP = 0.02
"""Height [m] of the base plate's lower face above the base frame (as drawn since the first URDFs)."""


def base_plate(material: str, radius: float, sizes: CollisionSizes) -> tuple[Any, Any]:
    """The base plate's visual and collision disk: `radius` [m], `sizes.plate_thickness` thick,
    its lower face `PLATE_GAP` above the base frame."""
    xyz = (0, 0, PLATE_GAP + 0.5 * sizes.plate_thickness)
    return (visual("cylinder", material, xyz=xyz, radius=radius, length=sizes.plate_thickness),
            collision("cylinder", xyz, radius=radius, length=sizes.plate_thickness))


def platform_sphere(radius: float) -> Any:
    """The platform's collision shape: the sphere of `radius` [m] about its centre."""
    return collision("sphere", radius=radius)


def collisions_block(sizes: CollisionSizes) -> dict[str, Any]:
    """The sidecar's `collisions` block: the shapes' sizes as generated (a record; the URDF's
    `<collision>` elements are what is read) and the disabled link pairs (none)."""
    return {"collisions": {"sizes": sizes.as_dict(), "disabled": []}}


COLLISIONS_NOTE = ("collisions: the collision shapes' sizes [m] as generated (the URDF's <collision> elements "
                   "are what is read) and link pairs never checked.")


def read_collision_sizes(sidecar: str | os.PathLike[str], default: CollisionSizes) -> CollisionSizes:
    """The sizes recorded in a sidecar's `collisions: sizes:` block (`default` where absent)."""
    import yaml

    raw = yaml.safe_load(Path(sidecar).read_text()) if Path(sidecar).exists() else None
    block = raw.get("collisions") if isinstance(raw, dict) else None
    sizes = block.get("sizes") if isinstance(block, dict) else None
    if not isinstance(sizes, dict):
        return default
    known = {f.name for f in dataclasses.fields(CollisionSizes)}
    bad = {k: v for k, v in sizes.items() if k in known and (isinstance(v, bool) or not isinstance(v, int | float))}
    if bad:
        raise ModelFileError(sidecar, f"collisions: sizes: expected numbers [m], got {bad}")
    return default.replace(**{k: float(v) for k, v in sizes.items() if k in known})


def axis_reference(ik: Callable[[Any, np.ndarray], Any], params: Any, half_span: float,
                   samples: int) -> tuple[np.ndarray, str]:
    """A platform position on the base's z axis, within |z| <= half_span [m] on `samples` points,
    where working mode '---' is assembled with every limit respected (mid-way along the valid
    stretch), else merely assembled: the reference configuration the generators write. `ik(params, points)` is the mechanism's vectorised IK."""
    z = np.linspace(-half_span, half_span, samples)
    pts = np.stack([np.zeros_like(z), np.zeros_like(z), z], axis=-1)
    res = ik(params, pts)
    mode = mode_index("---")
    for ok in (res.within_limits[:, mode], res.reachable[:, mode]):
        if ok.any():
            idx = np.flatnonzero(ok)
            return pts[idx[len(idx) // 2]], "---"
    raise InvalidInputError("design", "the platform cannot be assembled anywhere on the base's axis")


def rod_offset(k: int, s: float) -> float:
    """Offset of rod k across its limb [m]: rod 1 at -s/2, rod 2 at +s/2 (s: rod spacing)."""
    return -0.5 * s if k == 1 else 0.5 * s


def add_rod(urdf: UrdfBuilder, i: int, k: int, carrier: str, mount: tuple[str, tuple, tuple],
            first: tuple[str, tuple, tuple[float, float]], phi_limit: tuple[float, float], length: float,
            radius: float) -> None:
    """Rod (i, k): `mount` = (name, xyz, rpy) of the fixed mount joint on link `carrier`; `first`
    = (name, rpy, limit) of the universal joint's first revolute (axis y); the second, `u_phi_i_k`,
    turns about z within `phi_limit`; the tip sits `length` [m] along the rod's x; the rod is
    drawn as a cylinder and collides as a capsule of `radius` [m] between the joint centres."""
    name, xyz, rpy = mount
    urdf.joint(f"{name}_{i}_{k}_joint", "fixed", carrier, f"{name}_{i}_{k}", xyz=xyz, rpy=rpy)
    urdf.link(f"{name}_{i}_{k}", visual("sphere", "joint", radius=0.012))
    u_name, u_rpy, u_limit = first
    urdf.joint(f"{u_name}_{i}_{k}", "revolute", f"{name}_{i}_{k}", f"ucross_{i}_{k}", rpy=u_rpy, axis=(0, 1, 0),
               limit=u_limit)
    urdf.link(f"ucross_{i}_{k}")
    urdf.joint(f"u_phi_{i}_{k}", "revolute", f"ucross_{i}_{k}", f"rod_{i}_{k}", axis=(0, 0, 1), limit=phi_limit)
    urdf.link(f"rod_{i}_{k}", visual("cylinder", "rod", xyz=(0.5 * length, 0, 0), rpy=(0, 0.5 * math.pi, 0),
                                     radius=radius, length=length), *capsule((0, 0, 0), (length, 0, 0), radius))
    urdf.joint(f"tip_{i}_{k}_joint", "fixed", f"rod_{i}_{k}", f"tip_{i}_{k}", xyz=(length, 0, 0))
    urdf.link(f"tip_{i}_{k}", visual("sphere", "joint", radius=0.01))


def platform_mount(R_s3: np.ndarray, anchor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fixed placement (translation [m], rotation) from the s_3 body, of world orientation R_s3
    at s = 0, to the platform frame, so that anchor_1_1 (at `anchor` in platform axes) is the
    spherical joint's centre."""
    return R_s3.T @ (-anchor), R_s3.T


def add_platform(urdf: UrdfBuilder, mount: tuple[np.ndarray, np.ndarray], alpha: Sequence[float], radius: float,
                 anchor_y: Callable[[int], float], *visuals: Any) -> None:
    """The spherical joint from tip_1_1, the platform (`mount`: `platform_mount`; `visuals`: its
    visual and collision elements), and per limb i a frame `pmount_i` turned by alpha_i about z
    holding the anchors at (radius, anchor_y(k), 0)."""
    chain = ["tip_1_1", "sphere_a", "sphere_b", "sphere_c"]
    for jname, parent, child, axis in zip(SPHERICAL, chain[:-1], chain[1:], ((0, 0, 1), (0, 1, 0), (1, 0, 0)),
                                          strict=True):
        urdf.joint(jname, "revolute", parent, child, axis=axis, limit=(-math.pi, math.pi))
        urdf.link(child)
    xyz, R = mount
    urdf.joint("platform_joint", "fixed", "sphere_c", "platform", xyz=tuple(xyz), rpy=rpy_of(R))
    urdf.link("platform", *visuals)
    for i, a in zip(LIMBS, alpha, strict=True):
        urdf.joint(f"pmount_{i}_joint", "fixed", "platform", f"pmount_{i}", rpy=(0, 0, a))
        urdf.link(f"pmount_{i}")
        for k in RODS:
            urdf.joint(f"anchor_{i}_{k}_joint", "fixed", f"pmount_{i}", f"anchor_{i}_{k}", xyz=(radius, anchor_y(k), 0))
            urdf.link(f"anchor_{i}_{k}")


def mode_solution(limb_ik: Callable[[Any, np.ndarray], Any], params: Any, p: np.ndarray,
                  mode: str) -> tuple[np.ndarray, np.ndarray]:
    """(actuator values (3,), unit rod directions (3, 3)) with the platform at `p` [m] in working
    mode `mode`, from the family's `limb_ik`; InvalidInputError where a limb cannot reach."""
    pos = np.asarray(p, dtype=float).reshape(3)
    limbs = limb_ik(params, pos)
    roots = mode_roots(limbs.reach, pos, mode)
    return limbs.q[np.arange(3), roots], limbs.n[np.arange(3), roots]


def mode_solutions(limb_ik: Callable[[Any, np.ndarray], Any], params: Any, points: np.ndarray,
                   mode: str) -> tuple[np.ndarray, np.ndarray]:
    """`mode_solution` at many platform positions (N, 3) [m]: actuator values (N, 3) and unit rod
    directions (N, 3, 3); NaN where a limb cannot reach."""
    from kinematics.mechanisms.three_limb.modes import MODE_ROOTS

    limbs = limb_ik(params, np.asarray(points, dtype=float).reshape(-1, 3))
    roots, idx = MODE_ROOTS[mode_index(mode)], np.arange(3)
    return limbs.q[:, idx, roots], limbs.n[:, idx, roots]


def tree_arrays(model: Any, values: dict[str, np.ndarray]) -> np.ndarray:
    """Pinocchio configurations (N, nq) of `model` from the arrays `tree_values`' names map to
    (every joint of the model named, each with one coordinate)."""
    n = len(next(iter(values.values())))
    q = np.empty((n, model.nq))
    for j in range(1, model.njoints):
        q[:, model.idx_qs[j]] = values[model.names[j]]
    return q


def tree_values(actuator: str, q: np.ndarray, first: str, u_first: np.ndarray, u_phi: np.ndarray,
                s_2: float) -> dict[str, float]:
    """Joint values of the tree, by name: `{actuator}_i` = q_i, the universal joint's
    `{first}_i_k` and `u_phi_i_k` (both rods of a limb alike), and the platform's spherical
    joint: s_1 undoes rod (1, 1)'s u_phi, s_2 as given (the family's elevation term), s_3 = 0
    (the platform does not turn)."""
    arrays = tree_value_arrays(actuator, np.asarray(q)[None], first, np.asarray(u_first)[None],
                               np.asarray(u_phi)[None], np.array([s_2]))
    return {name: float(v[0]) for name, v in arrays.items()}


def tree_value_arrays(actuator: str, q: np.ndarray, first: str, u_first: np.ndarray, u_phi: np.ndarray,
                      s_2: np.ndarray) -> dict[str, np.ndarray]:
    """`tree_values` at N poses: q, u_first, u_phi (N, 3), s_2 (N,); arrays (N,) by joint name."""
    values: dict[str, np.ndarray] = {}
    for i in LIMBS:
        values[f"{actuator}_{i}"] = q[:, i - 1]
        for k in RODS:
            values[f"{first}_{i}_{k}"] = u_first[:, i - 1]
            values[f"u_phi_{i}_{k}"] = u_phi[:, i - 1]
    values["s_1"] = -values["u_phi_1_1"]
    values["s_2"] = s_2 + 0.0
    values["s_3"] = np.zeros(len(q))
    return values


def sidecar_text(mechanism: str, command: str, urdf_name: str, actuated: str, reference: dict[str, float],
                 extra: dict[str, Any] | None = None, notes: Sequence[str] = ()) -> str:
    """The loop sidecar (YAML, `yaml.safe_dump`) of a three-limb URDF: actuated joints
    `{actuated}_1..3`, the five rod closures, `extra` keys, the `reference` configuration; a
    header comment says it is generated by `command` (quoted as it should print), with `notes` lines after it."""
    import yaml

    data: dict[str, Any] = {"format": FORMAT, "mechanism": mechanism, "urdf": urdf_name, "end_effector": "platform",
                            "actuated": [f"{actuated}_{i}" for i in LIMBS], **(extra or {})}
    data["closures"] = [{"name": f"S_{i}_{k}", "type": "point", "frame1": f"tip_{i}_{k}", "frame2": f"anchor_{i}_{k}"}
                        for i in LIMBS for k in RODS if (i, k) != (1, 1)]  # rod (1, 1) carries the platform
    ref = {"reference": {name: float(value) + 0.0 for name, value in reference.items()}}  # + 0.0: no -0.0
    header = [f"Loop closures of {urdf_name} ({mechanism}). Generated by {command}; do not edit.",
              "closures: each pair of frames must coincide (a 3D point constraint = a ball joint).",
              "reference: an assembled configuration (loops closed), the closed-loop solver's start.", *notes]
    # short lists and closures on one line each (flow style), the reference one joint a line
    body = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120)
    body += yaml.safe_dump(ref, sort_keys=False, default_flow_style=False)
    return "".join(f"# {line}\n" for line in header) + body


Writer = Callable[..., tuple[Path, Path]]
"""`write(params, path, name=None, sizes=None) -> (URDF path, sidecar path)`."""


def writer(urdf_text: Callable[[Any, str], str], sidecar_text: Callable[[Any, str], str]) -> Writer:
    """A family's `write(params, path, name=None, sizes=None)`: the URDF `urdf_text(params, name
    or the file's stem, sizes)` to `path` and `sidecar_text(params, URDF file name, sizes)` beside it
    (`sizes`: the collision shapes' `CollisionSizes`, the family's defaults when None)
    (`model.loops.sidecar_for`), returning both paths. Both are written as one
    (`files.write_atomic_files`): on any failure neither file is half-written, and files already
    there are left as they were."""

    def write(params: Any, path: str | os.PathLike[str], name: str | None = None,
              sizes: CollisionSizes | None = None) -> tuple[Path, Path]:
        from kinematics.files import write_atomic_files

        urdf_path = Path(path)
        side = sidecar_for(urdf_path)
        extra = {} if sizes is None else {"sizes": sizes}
        urdf = urdf_text(params, name or urdf_path.stem, **extra)
        loops = sidecar_text(params, urdf_path.name, **extra)
        if not urdf_path.parent.is_dir():
            raise ModelFileError(urdf_path.parent, "output directory does not exist")
        write_atomic_files([(str(urdf_path), urdf), (str(side), loops)], "output")
        return urdf_path, side

    write.__doc__ = writer.__doc__
    return write
