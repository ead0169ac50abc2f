"""Gepetto-format loop descriptions: a `robot.yaml` beside a URDF, as in Gepetto's
example-parallel-robots, read into this toolkit's `LoopSpec`.

The format (all lists; order matters where two lists pair up)::

    closed_loop: [[frame_A, frame_B], ...]   # frame pairs that coincide when a loop is closed
    type: ['6D', '3D', ...]                   # per pair: 3D = positions equal (a spherical joint),
                                              # 6D = placements equal (a weld); absent: all 6D
    name_mot: [joint, ...]                    # motor (actuated) joints, in actuator order
    joint_name: [joint, ...]                  # optional: URDF joints whose model is replaced ...
    joint_type: [SPHERICAL, ...]              # ... by this one (paired with joint_name)

Supported substitutions (the URDF joint's origin is kept; its axis is ignored; the revolutes
that replace it are passive and get no range, like the format's free joints):

* ``SPHERICAL``: three revolutes about the joint frame's x, y and z axes through its origin,
  named ``<joint>_X``, ``<joint>_Y``, ``<joint>_Z`` (Pinocchio's spherical joint has a quaternion
  configuration, which this toolkit's one-value-per-freedom joint table does not model; the
  x-y-z chain is singular only when the ``_Y`` angle is +/-90 deg).
* ``UJOINT_<A><B>`` for any ordered pair of distinct axes A, B of X, Y, Z (``UJOINT_ZY``,
  ``UJOINT_XZ``, ...; the older ``CARDAN`` = ``UJOINT_XY``): two revolutes about the named
  axes, ``<joint>_<A>`` then ``<joint>_<B>``.
* ``FIXED``: the joint is locked at its zero value.

Refused, each with a `GepettoFormatError` that names the key and what is wrong: the older
name-pattern files (``name_mot: "mot"``, ``name_closedloop``, ``closed_loop_number``), unknown
keys, closure types other than 3D/6D, lists of different lengths, unknown motor or frame names,
a motor that is substituted, and joint types outside the list above. A substitution of a joint the
URDF lacks is left out with a `KinematicsWarning`, as Gepetto's loader skips it. The end effector, which the
format does not name, is the `load_robot(..., tool_frame=...)` frame, else a frame named
``effector`` (the examples' convention), else the first frame of the first pair.
"""

from __future__ import annotations

import copy
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pinocchio as pin

from kinematics.errors import KinematicsWarning, ModelFileError, UnknownFrameError, UnknownJointError, closest
from kinematics.files import read_text
from kinematics.model.loops import Closure, LoopSpec

FILENAME = "robot.yaml"
"""Name of the Gepetto description beside the URDF."""

KEYS: tuple[str, ...] = ("closed_loop", "type", "name_mot", "joint_name", "joint_type")
"""Every key the reader accepts (a YAML file with none of them is not a Gepetto description)."""

LEGACY_KEYS: tuple[str, ...] = ("name_closedloop", "closed_loop_number")

SUBSTITUTIONS: dict[str, str] = {
    "SPHERICAL": "XYZ",
    **{f"UJOINT_{a}{b}": f"{a}{b}" for a in "XYZ" for b in "XYZ" if a != b},
    "CARDAN": "XY",
    "FIXED": "",
}
"""Supported `joint_type` values -> the revolute axes that replace the joint ("" = locked)."""

CLOSURE_TYPES: dict[str, str] = {"3d": "point", "6d": "6d"}
"""Gepetto closure types (case-insensitive) -> this toolkit's closure types."""

_AXES = {"X": "1 0 0", "Y": "0 1 0", "Z": "0 0 1"}


class GepettoFormatError(ModelFileError):
    """A Gepetto `robot.yaml` that is malformed or uses something this reader does not support.

    Attributes:
        key: the offending key of the file (None for the file as a whole).
    """

    def __init__(self, path: object, problem: str, key: str | None = None) -> None:
        self.key = key
        super().__init__(path, f"{key}: {problem}" if key else problem)


@dataclass(frozen=True)
class GepettoSpec:
    """A parsed Gepetto `robot.yaml`, before it is checked against a model.

    Attributes:
        path: the YAML file.
        pairs: (frame_A, frame_B, closure type "point" or "6d") per closed loop.
        motors: actuated joint names, in actuator order.
        substitutions: URDF joint name -> `SUBSTITUTIONS` key.
    """

    path: Path
    pairs: tuple[tuple[str, str, str], ...]
    motors: tuple[str, ...]
    substitutions: tuple[tuple[str, str], ...] = ()

    def joint_names(self, joint: str) -> tuple[str, ...]:
        """Names of the joints that replace URDF joint `joint` (empty if locked)."""
        axes = dict(self.substitutions).get(joint)
        return (joint,) if axes is None else tuple(f"{joint}_{a}" for a in SUBSTITUTIONS[axes])


def gepetto_file_for(urdf_path: str | os.PathLike[str]) -> Path:
    """`dir/anything.urdf` -> `dir/robot.yaml`."""
    return Path(urdf_path).with_name(FILENAME)


def _string_list(path: Path, raw: dict[str, Any], key: str) -> list[str]:
    value = raw.get(key)
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise GepettoFormatError(path, f"expected a list of names, got {value!r}", key)
    return value


def read_gepetto(path: str | os.PathLike[str]) -> GepettoSpec | None:
    """Parse a Gepetto `robot.yaml`; None if the YAML has none of the format's keys.

    Raises:
        GepettoFormatError: malformed or unsupported content (the message names the key).
    """
    import yaml

    p = Path(path)
    try:
        raw = yaml.safe_load(read_text(p, GepettoFormatError))
    except yaml.YAMLError as exc:
        raise GepettoFormatError(p, f"malformed YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(raw, dict) or not set(raw) & set(KEYS + LEGACY_KEYS):
        return None
    legacy = [k for k in LEGACY_KEYS if k in raw] or (["name_mot"] if isinstance(raw.get("name_mot"), str) else [])
    if legacy:
        raise GepettoFormatError(p, "the name-pattern form of the format (name_mot as a pattern, name_closedloop, "
                                 "closed_loop_number) is not supported; list the frame pairs in closed_loop and the "
                                 "motor joints in name_mot", legacy[0])
    unknown = sorted(set(raw) - set(KEYS))
    if unknown:
        raise GepettoFormatError(p, f"unknown key(s) {', '.join(map(repr, unknown))}; valid: {', '.join(KEYS)}")
    for key in ("closed_loop", "name_mot"):
        if key not in raw:
            raise GepettoFormatError(p, "missing (required)", key)
    loops = raw["closed_loop"]
    if not isinstance(loops, list) or not all(
        isinstance(pair, list) and len(pair) == 2 and all(isinstance(n, str) for n in pair) for pair in loops
    ):
        raise GepettoFormatError(p, f"expected a list of [frame_A, frame_B] pairs, got {loops!r}", "closed_loop")
    types = _string_list(p, raw, "type") if "type" in raw else ["6D"] * len(loops)
    if len(types) != len(loops):
        raise GepettoFormatError(p, f"{len(types)} type(s) for {len(loops)} closed_loop pair(s)", "type")
    kinds = []
    for t in types:
        if t.lower() not in CLOSURE_TYPES:
            raise GepettoFormatError(p, f"unsupported closure type {t!r}; valid: 3D, 6D", "type")
        kinds.append(CLOSURE_TYPES[t.lower()])
    motors = _string_list(p, raw, "name_mot")
    if len(set(motors)) != len(motors):
        raise GepettoFormatError(p, f"a motor is listed twice: {motors}", "name_mot")
    names = _string_list(p, raw, "joint_name") if "joint_name" in raw else []
    jtypes = _string_list(p, raw, "joint_type") if "joint_type" in raw else []
    if len(names) != len(jtypes):
        raise GepettoFormatError(p, f"{len(jtypes)} joint_type(s) for {len(names)} joint_name(s)", "joint_type")
    if len(set(names)) != len(names):
        raise GepettoFormatError(p, f"a joint is listed twice: {names}", "joint_name")
    for t in jtypes:
        if t not in SUBSTITUTIONS:
            hint = closest(t, SUBSTITUTIONS)
            raise GepettoFormatError(p, f"unsupported joint type {t!r}"
                                     + (f" (did you mean {' or '.join(map(repr, hint))}?)" if hint else "")
                                     + f"; valid: {', '.join(SUBSTITUTIONS)}", "joint_type")
    for m in motors:
        if m in names:
            raise GepettoFormatError(p, f"motor {m!r} is substituted ({jtypes[names.index(m)]}) in joint_name; "
                                     "a motor must stay a 1-DOF joint", "name_mot")
    pairs = tuple((a, b, k) for (a, b), k in zip(loops, kinds, strict=True))
    return GepettoSpec(p, pairs, tuple(motors), tuple(zip(names, jtypes, strict=True)))


def substitute_joints(root: ET.Element, spec: GepettoSpec) -> ET.Element:
    """A copy of the URDF tree `root` with each substituted joint replaced (see module doc).

    A substitution naming a joint the URDF lacks is left out with a `KinematicsWarning` (naming the
    closest joints), as Gepetto's loader skips it.

    Raises:
        GepettoFormatError: a substituted joint is fixed, or a new name collides.
    """
    out = copy.deepcopy(root)
    joints = {j.get("name"): j for j in out.findall("joint")}
    links = {lk.get("name") for lk in out.findall("link")}
    for name, kind in spec.substitutions:
        joint = joints.get(name)
        if joint is None:
            # Gepetto's loader applies a substitution only to the joints it finds, so its models
            # load with such a name (disney_robot's URDF misspells one); so do they here, loudly
            import warnings

            near = closest(name, [n for n in joints if n and joints[n].get("type") != "fixed"])
            guess = f" (did you mean {' or '.join(repr(n) for n in near)}?)" if near else ""
            warnings.warn(KinematicsWarning(
                f"{spec.path}: joint_name lists {name!r}, which the URDF does not have{guess}; its {kind} "
                "substitution is left out (as Gepetto's loader does), so that joint keeps its URDF type"),
                stacklevel=2)
            continue
        if joint.get("type") in ("fixed", "floating", "planar"):
            raise GepettoFormatError(spec.path, f"joint {name!r} is a {joint.get('type')} joint in the URDF; only "
                                     "revolute, continuous and prismatic joints can be substituted", "joint_name")
        axes = SUBSTITUTIONS[kind]
        if not axes:
            joint.set("type", "fixed")
            for tag in ("axis", "limit", "mimic", "dynamics", "calibration", "safety_controller"):
                for el in joint.findall(tag):
                    joint.remove(el)
            continue
        parent = joint.find("parent")
        child = joint.find("child")
        origin = joint.find("origin")
        index = list(out).index(joint)
        out.remove(joint)
        new_names = [f"{name}_{a}" for a in axes]
        new_links = [f"{name}_{a}_link" for a in axes[:-1]]
        clash = [n for n in new_names if n in joints] + [n for n in new_links if n in links]
        if clash:
            raise GepettoFormatError(spec.path, f"substituting {name!r} ({kind}) needs the name(s) {clash}, which "
                                     "the URDF already uses", "joint_name")
        chain = [(parent.get("link") or "") if parent is not None else "", *new_links]
        chain.append((child.get("link") or "") if child is not None else "")
        elements = [ET.Element("link", name=n) for n in new_links]
        for k, (jname, axis) in enumerate(zip(new_names, axes, strict=True)):
            j = ET.Element("joint", name=jname, type="revolute")
            ET.SubElement(j, "parent", link=chain[k])
            ET.SubElement(j, "child", link=chain[k + 1])
            if k == 0 and origin is not None:
                j.append(copy.deepcopy(origin))
            ET.SubElement(j, "axis", xyz=_AXES[axis])
            ET.SubElement(j, "limit", effort="1", velocity="1")  # no range: unbounded
            elements.append(j)
        for offset, el in enumerate(elements):
            out.insert(index + offset, el)
    return out


def build_model(urdf_path: str | os.PathLike[str], spec: GepettoSpec) -> tuple[pin.Model, ET.Element]:
    """The Pinocchio model (fixed base) of the URDF with `spec`'s joint substitutions applied,
    and the URDF tree it was built from."""
    from kinematics.model.urdf_file import check_urdf_file, read_urdf

    if not spec.substitutions:
        return read_urdf(urdf_path)
    root = check_urdf_file(urdf_path)
    root = substitute_joints(root, spec)
    try:
        return pin.buildModelFromXML(ET.tostring(root, encoding="unicode")), root
    except (ValueError, RuntimeError) as exc:
        raise ModelFileError(urdf_path, f"Pinocchio cannot parse it after the substitutions of {spec.path}: "
                             f"{exc}") from None


def loop_spec(spec: GepettoSpec, model: pin.Model, end_effector: str | None = None) -> LoopSpec:
    """Check `spec` against `model` (built by `build_model`) and convert it to a `LoopSpec`.

    Raises:
        UnknownJointError: a motor is not a joint of the model.
        UnknownFrameError: a closure frame (or `end_effector`) is not a frame of the model.
        GepettoFormatError: a closure names the frame of a joint that was substituted.
    """
    frames = list(dict.fromkeys(f.name for f in model.frames))
    joints = list(model.names)[1:]
    substituted = dict(spec.substitutions)
    for m in spec.motors:
        if m not in joints:
            raise UnknownJointError(m, joints)
    closures = []
    for k, (a, b, kind) in enumerate(spec.pairs):
        for f in (a, b):
            if f in substituted:
                raise GepettoFormatError(spec.path, f"pair #{k + 1} names {f!r}, the frame of a joint substituted "
                                         f"by {substituted[f]}; name a link frame instead", "closed_loop")
            if not model.existFrame(f):
                raise UnknownFrameError(f, frames)
        closures.append(Closure(f"closed_loop_{k + 1}", a, b, kind))  # type: ignore[arg-type]
    if end_effector is None:
        end_effector = "effector" if model.existFrame("effector") else (closures[0].frame1 if closures else frames[-1])
    elif not model.existFrame(end_effector):
        raise UnknownFrameError(end_effector, frames)
    return LoopSpec(path=spec.path, actuated=spec.motors, closures=tuple(closures), end_effector=end_effector)


def find_gepetto(urdf_path: str | os.PathLike[str]) -> GepettoSpec | None:
    """The Gepetto description beside `urdf_path`, parsed; None if absent or not in that format."""
    path = gepetto_file_for(urdf_path)
    return read_gepetto(path) if path.is_file() else None
