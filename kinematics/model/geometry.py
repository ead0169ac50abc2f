"""A robot's visual or collision geometry from its URDF, as a Pinocchio `GeometryModel`.

Pinocchio's URDF parser (urdfdom) skips a `<visual>`/`<collision>` whose shape it does not know
(e.g. `<capsule>`) with a message on stderr only, and raises on the first mesh file it cannot find.
`geometry_model` makes both explicit: meshes that are missing are left out and listed (views draw
the rest), and for collision geometry, where a silently missing body would make a robot look free
where it collides, an unknown shape or a missing mesh raises `GeometryError`.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any, Literal

from kinematics.errors import ModelFileError

SHAPES = ("box", "cylinder", "sphere", "mesh")
"""The URDF geometry elements Pinocchio reads."""

Kind = Literal["visual", "collision"]


class GeometryError(ModelFileError):
    """A URDF's collision geometry cannot be loaded whole: a shape Pinocchio does not read, or a
    mesh file that is not found. Carries the offending elements as `problems`."""

    def __init__(self, path: str | Path, problems: list[str]) -> None:
        self.problems = tuple(problems)
        super().__init__(path, "collision geometry not loaded whole: " + "; ".join(problems)
                         + f" (shapes read: {', '.join(SHAPES)})")


def mesh_file(name: str, here: Path, package_dirs: list[str]) -> str | None:
    """Where a URDF mesh filename points, as Pinocchio resolves it (package:// in the package
    directories, file:// and absolute as given, relative to the URDF's folder), if it exists."""
    if name.startswith("package://"):
        candidates = [Path(d) / name.removeprefix("package://") for d in package_dirs]
    else:
        candidates = [here / name.removeprefix("file://")]  # an absolute name ignores `here`
    return next((str(c) for c in candidates if c.is_file()), None)


def geometry_model(robot: Any, kind: Kind = "visual", urdf_text: str | None = None) -> tuple[Any, list[str]]:
    """The robot's `pin.GeometryModel` of `kind` and a line per element left out.

    Args:
        robot: a loaded `Robot` (its model, URDF path and package directories are used).
        kind: "visual" leaves out (and lists) elements whose mesh is missing or whose shape is not
            read; "collision" raises `GeometryError` for either instead.
        urdf_text: the URDF to read instead of `robot.urdf_path`'s (e.g. with collision shapes
            added); relative mesh names still resolve against `robot.urdf_path`'s folder.

    Returns:
        (geometry model, skipped): with every mesh filename made absolute, so the result does not
        depend on the working directory.
    """
    import pinocchio as pin

    path = Path(robot.urdf_path)
    dirs = list(robot.package_dirs) + [d for d in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if d]
    root = ET.fromstring(path.read_text(encoding="utf-8") if urdf_text is None else urdf_text)
    skipped: list[str] = []
    for link in root.iter("link"):
        for element in list(link.findall(kind)):
            problem = _problem(element, path.parent, dirs)
            if problem is not None:
                link.remove(element)
                skipped.append(f"link {link.get('name')}: {problem}")
    if skipped and kind == "collision":
        raise GeometryError(path, skipped)
    geom_type = pin.GeometryType.VISUAL if kind == "visual" else pin.GeometryType.COLLISION
    text = ET.tostring(root, encoding="unicode")
    try:
        return pin.buildGeomFromUrdfString(robot.model, text, geom_type, package_dirs=dirs or None), skipped
    except ValueError as exc:  # a mesh file that is found but cannot be read
        raise ModelFileError(path, f"{kind} geometry not loaded: {load_failure(exc)}") from None


def load_failure(exc: Exception) -> str:
    """The reason in coal's (or Pinocchio's) message for a mesh it could not load, on one line:
    theirs spans lines (source file, function, line, reason, a hint that the mesh directory may
    be wrong, also given when the file was found but is not a mesh)."""
    reason = [line.removeprefix("message: ") for line in str(exc).splitlines()
              if line.strip() and not line.startswith(("From file:", "in function:", "at line:", "Hint:"))]
    return " ".join(reason) or type(exc).__name__


def _problem(element: ET.Element, here: Path, dirs: list[str]) -> str | None:
    """Why Pinocchio would not load this <visual>/<collision> element, or None; resolves its mesh
    filename in place."""
    geometry = element.find("geometry")
    shapes = [] if geometry is None else list(geometry)
    if len(shapes) != 1 or shapes[0].tag not in SHAPES:
        return f"shape {', '.join(s.tag for s in shapes) or 'missing'} not read"
    if shapes[0].tag == "mesh":
        name = shapes[0].get("filename", "")
        found = mesh_file(name, here, dirs)
        if found is None:
            return f"mesh {name} not found"
        shapes[0].set("filename", found)
    return None
