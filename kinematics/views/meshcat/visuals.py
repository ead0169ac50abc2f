"""A robot's visual model from its URDF, leaving out the visuals whose mesh file is missing, and
the world corners of its visuals' bounding boxes (what a camera must frame)."""

from __future__ import annotations

from typing import Any

import numpy as np

from kinematics.model.geometry import geometry_model


def visual_model(robot: Any) -> tuple[Any, list[str]]:
    """The robot's visual GeometryModel and a line per <visual> left out because its mesh file is
    missing or its shape is not one Pinocchio reads: the rest stays."""
    return geometry_model(robot, "visual")


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
