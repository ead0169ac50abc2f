"""A robot's visual model from its URDF, leaving out the visuals whose mesh file is missing, and
the world corners of its visuals' bounding boxes (what a camera must frame)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np


def visual_model(robot: Any) -> tuple[Any, list[str]]:
    """The robot's visual GeometryModel and a line per <visual> left out because its mesh file is
    missing (Pinocchio raises on the first one): the primitives and the meshes that exist stay."""
    import xml.etree.ElementTree as ET

    import pinocchio as pin

    path = Path(robot.urdf_path)
    dirs = list(robot.package_dirs)
    try:
        return pin.buildGeomFromUrdf(robot.model, str(path), pin.GeometryType.VISUAL, package_dirs=dirs or None), []
    except ValueError as exc:
        if "could not be found" not in str(exc):
            raise
    dirs += [d for d in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if d]
    root = ET.fromstring(path.read_text(encoding="utf-8"))
    skipped: list[str] = []
    for link in root.iter("link"):
        for vis in list(link.findall("visual")):
            for mesh in vis.iter("mesh"):
                name = mesh.get("filename", "")
                found = _mesh_file(name, path.parent, dirs)
                if found is None:
                    link.remove(vis)
                    skipped.append(f"link {link.get('name')}: {name}")
                    break
                mesh.set("filename", found)  # absolute: the string below has no directory
    return pin.buildGeomFromUrdfString(robot.model, ET.tostring(root, encoding="unicode"), pin.GeometryType.VISUAL,
                                       package_dirs=dirs or None), skipped


def _mesh_file(name: str, here: Path, package_dirs: list[str]) -> str | None:
    """Where a URDF mesh filename points, as Pinocchio resolves it (package:// in the package
    directories, file:// and absolute as given, relative to the URDF's folder), if it exists."""
    if name.startswith("package://"):
        candidates = [Path(d) / name.removeprefix("package://") for d in package_dirs]
    else:
        candidates = [here / name.removeprefix("file://")]  # an absolute name ignores `here`
    return next((str(c) for c in candidates if c.is_file()), None)


def corners(geometry: Any, data: Any) -> np.ndarray:
    """World corners [m] of every visual's local bounding box, at the placements in `data`."""
    out = []
    signs = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
    for g, M in zip(geometry.geometryObjects, data.oMg, strict=True):
        g.geometry.computeLocalAABB()
        box = g.geometry.aabb_local
        lo, hi = np.asarray(box.min_), np.asarray(box.max_)  # meshes are loaded scaled
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            continue
        local = lo + signs * (hi - lo)
        out.append(local @ M.rotation.T + M.translation)
    return np.vstack(out) if out else np.zeros((0, 3))
