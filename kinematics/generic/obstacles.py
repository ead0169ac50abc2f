"""Obstacles: fixed bodies in the world frame that a robot must not touch, read from a file.

Two formats, told apart by the file's suffix:

* **URDF** (`.urdf`): a robot that does not move. Its root link is the world frame (the robot's
  base frame); every joint is fixed; each link's `<collision>` elements (box, cylinder, sphere,
  mesh; a cylinder with a sphere of its radius on each end face is a capsule) are obstacles named
  after their link. Mesh names resolve against the file's folder (or `package://`, `file://`).
* **YAML** (`.yaml`, `.yml`): a list of shapes with a pose (xyz [m], rpy [rad], URDF's
  convention; both default to zero)::

      obstacles:
        - {name: table, box: [1.0, 0.6, 0.05], xyz: [0.5, 0, -0.025]}   # full sizes [m]
        - {name: post, cylinder: [0.04, 1.0], xyz: [0.3, 0.3, 0.5]}     # radius, length (along z)
        - {name: bar, capsule: [0.02, 0.5]}                               # radius, length (along z)
        - {name: lamp, sphere: 0.1, xyz: [0, 0, 1.2]}                     # radius
        - {name: wall, halfspace: [-1, 0, 0, -0.35]}                      # n, d: the solid n.x <= d
        - {name: part, mesh: part.stl, scale: [0.001, 0.001, 0.001]}      # relative to the YAML's folder

The result is a `pin.GeometryModel` whose objects all hang on the universe joint (joint 0, frame
0), placed in the world frame, with `obstacle_links` naming the body each belongs to; the collision
model (`kinematics.generic.collision.CollisionModel.from_robot(obstacles=...)`) checks each
against every moving body of the robot.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from kinematics.errors import InvalidInputError, ModelFileError
from kinematics.files import read_text

SHAPES = ("box", "cylinder", "capsule", "sphere", "halfspace", "mesh")
"""The YAML format's shape keys."""


class Obstacles:
    """Fixed obstacles: `geometry` (a `pin.GeometryModel` on joint 0, world placements) and
    `links[k]`, the obstacle body of geometry k; `path` the file they came from."""

    def __init__(self, geometry: Any, links: list[str], path: str) -> None:
        self.geometry, self.links, self.path = geometry, tuple(links), path

    @property
    def names(self) -> tuple[str, ...]:
        """The obstacle bodies, in file order, once each."""
        return tuple(dict.fromkeys(self.links))


def load_obstacles(path: str | Path) -> Obstacles:
    """Read an obstacle file (module docstring): a URDF of fixed bodies or a YAML list of shapes.

    Raises:
        ModelFileError: the file is missing, malformed, moves (a URDF with a movable joint), or
            holds a shape that cannot be read (unknown, bad size, missing mesh).
    """
    p = Path(path)
    if not p.is_file():
        raise ModelFileError(p, "obstacle file not found")
    suffix = p.suffix.lower()
    if suffix == ".urdf":
        return _from_urdf(p)
    if suffix in (".yaml", ".yml"):
        return _from_yaml(p)
    raise ModelFileError(p, "obstacle file must be a .urdf or a .yaml/.yml")


def _from_urdf(path: Path) -> Obstacles:
    import pinocchio as pin

    from kinematics.model.geometry import SHAPES as URDF_SHAPES
    from kinematics.model.geometry import load_failure, mesh_file

    try:
        root = ET.fromstring(read_text(path))
    except ET.ParseError as exc:
        raise ModelFileError(path, f"not XML: {exc}") from None
    moving = [j.get("name", "?") for j in root.iter("joint") if j.get("type") != "fixed"]
    if moving:
        raise ModelFileError(path, f"obstacles do not move: joints {', '.join(moving)} are not fixed")
    problems = []
    for link in root.iter("link"):
        for element in link.findall("collision"):
            geometry = element.find("geometry")
            shapes = [] if geometry is None else list(geometry)
            if len(shapes) != 1 or shapes[0].tag not in URDF_SHAPES:
                problems.append(f"link {link.get('name')}: shape {', '.join(s.tag for s in shapes) or 'missing'} "
                                f"not read (shapes read: {', '.join(URDF_SHAPES)})")
            elif shapes[0].tag == "mesh":
                found = mesh_file(shapes[0].get("filename", ""), path.parent, [str(path.parent)])
                if found is None:
                    problems.append(f"link {link.get('name')}: mesh {shapes[0].get('filename')} not found")
                else:
                    shapes[0].set("filename", found)
    if problems:
        raise ModelFileError(path, "; ".join(problems))
    text = ET.tostring(root, encoding="unicode")
    model = pin.buildModelFromXML(text)
    try:
        loaded = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
    except ValueError as exc:  # a mesh file that is found but cannot be read
        raise ModelFileError(path, f"not loaded: {load_failure(exc)}") from None
    if loaded.ngeoms == 0:
        raise ModelFileError(path, "no <collision> element: no obstacle")
    out = pin.GeometryModel()
    links = []
    for g in loaded.geometryObjects:
        # fixed joints fold into frames of the universe joint: the placement is already the world's
        out.addGeometryObject(pin.GeometryObject(g.name, 0, 0, g.placement, g.geometry))
        links.append(model.frames[g.parentFrame].name)
    return Obstacles(out, links, str(path))


def _from_yaml(path: Path) -> Obstacles:
    import pinocchio as pin
    import yaml

    try:
        data = yaml.safe_load(read_text(path))
    except yaml.YAMLError as exc:  # the parser's own message spans lines (it quotes the text)
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise ModelFileError(path, f"not YAML: {getattr(exc, 'problem', None) or type(exc).__name__}{where}") from None
    items = data.get("obstacles") if isinstance(data, dict) else None
    if not isinstance(items, list) or not items:
        raise ModelFileError(path, "expected a non-empty list under 'obstacles:'")
    out = pin.GeometryModel()
    links = []
    for k, item in enumerate(items):
        if not isinstance(item, dict):
            raise ModelFileError(path, f"obstacle {k}: expected a mapping, got {item!r}")
        name = str(item.get("name", f"obstacle_{k}"))
        keys = [s for s in SHAPES if s in item]
        if len(keys) != 1:
            raise ModelFileError(path, f"obstacle {name}: give exactly one shape of {', '.join(SHAPES)}")
        try:
            shape = _shape(keys[0], item[keys[0]], item.get("scale"), path.parent)
            placement = pin.SE3(pin.rpy.rpyToMatrix(*_floats(item.get("rpy", [0, 0, 0]), 3, "rpy")),
                                np.array(_floats(item.get("xyz", [0, 0, 0]), 3, "xyz")))
        except (InvalidInputError, ValueError, TypeError) as exc:
            raise ModelFileError(path, f"obstacle {name}: {exc}") from None
        if name in links:
            raise ModelFileError(path, f"obstacle name {name} given twice")
        out.addGeometryObject(pin.GeometryObject(name, 0, 0, placement, shape))
        links.append(name)
    return Obstacles(out, links, str(path))


def _floats(value: Any, n: int, what: str = "size") -> list[float]:
    try:  # (a mapping such as {radius: 0.05, length: 1.0} is no list of numbers: said as such)
        values = [float(v) for v in (value if isinstance(value, list | tuple) else [value])]
    except (TypeError, ValueError):
        values = []
    if len(values) != n or not all(np.isfinite(values)):
        raise InvalidInputError(what, f"expected {n} finite numbers, got {value!r}")
    return values


def _shape(kind: str, value: Any, scale: Any, here: Path) -> Any:
    """The coal shape of one YAML entry (sizes checked positive)."""
    import coal

    if kind == "mesh":
        from kinematics.model.geometry import load_failure, mesh_file

        found = mesh_file(str(value), here, [str(here)])
        if found is None:
            raise InvalidInputError("mesh", f"{value} not found")
        s = np.array(_floats(scale if scale is not None else [1, 1, 1], 3, "scale"))
        try:
            return coal.MeshLoader().load(found, s)
        except ValueError as exc:  # coal's message spans lines (source file, function, reason)
            raise InvalidInputError("mesh", f"cannot load {value}: {load_failure(exc)}") from None
    if kind == "halfspace":
        n = np.array(_floats(value, 4, "halfspace"))
        norm = float(np.linalg.norm(n[:3]))
        if norm == 0.0:
            raise InvalidInputError("halfspace", "the normal is zero")
        return coal.Halfspace(n[:3] / norm, float(n[3] / norm))
    sizes = _floats(value, {"box": 3, "cylinder": 2, "capsule": 2, "sphere": 1}[kind])
    if min(sizes) <= 0:
        raise InvalidInputError(kind, f"sizes must be positive, got {value!r}")
    if kind == "box":
        return coal.Box(*sizes)
    if kind == "sphere":
        return coal.Sphere(sizes[0])
    return (coal.Cylinder if kind == "cylinder" else coal.Capsule)(sizes[0], sizes[1])
