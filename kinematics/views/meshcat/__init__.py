"""Meshcat views: robots from their URDF visuals through Pinocchio's MeshcatVisualizer, with
overlays (manipulability ellipse/ellipsoid, workspace point clouds coloured by a measure, singular
points, an animated guidance run), served live or exported as one self-contained HTML file.

Modules:

* `scene`: `Scene`, its camera, robots, overlays and output (HTML, export, screenshot, notebook).
* `recording`: the in-memory back end (a recording meshcat window, the viewer's JavaScript).
* `visuals`: a robot's visual model, the visuals whose mesh file is missing left out.
* `skeletons`: the kinematic skeleton, its objects' transforms and its drawing.
* `materials`: colours and materials as meshcat takes them.
* `serial_views`: `scara_view`, `serial_view`, `default_pose`.
* `mechanism_views`: `closed_loop_view`, `parallel_view`, `conditioning_view`, `closed_loop_pose`.
"""

from __future__ import annotations

from kinematics.views.meshcat.mechanism_views import (
    OPEN_LOOP_RTOL,
    closed_loop_pose,
    closed_loop_view,
    conditioning_view,
    parallel_view,
)
from kinematics.views.meshcat.scene import BACKGROUND, FOV_DEG, GRID_SQUARES, Scene
from kinematics.views.meshcat.serial_views import (
    NEAR_SINGULAR,
    VIEW_CELLS,
    default_pose,
    scara_view,
    serial_view,
)
from kinematics.views.meshcat.skeletons import (
    SKELETON_SIZE,
    SKELETON_STYLE,
    Skeleton,
    SkeletonJoint,
    skeleton,
    skeleton_transforms,
)
from kinematics.views.meshcat.visuals import visual_model

__all__ = [
    "BACKGROUND",
    "FOV_DEG",
    "GRID_SQUARES",
    "NEAR_SINGULAR",
    "OPEN_LOOP_RTOL",
    "SKELETON_SIZE",
    "SKELETON_STYLE",
    "VIEW_CELLS",
    "Scene",
    "Skeleton",
    "SkeletonJoint",
    "closed_loop_pose",
    "closed_loop_view",
    "conditioning_view",
    "default_pose",
    "parallel_view",
    "scara_view",
    "serial_view",
    "skeleton",
    "skeleton_transforms",
    "visual_model",
]
