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
* `collision_views`: colliding workspace points by binding pair, obstacles.
"""

from __future__ import annotations

from kinematics.views.meshcat.mechanism_views import closed_loop_pose as closed_loop_pose
from kinematics.views.meshcat.mechanism_views import closed_loop_view as closed_loop_view
from kinematics.views.meshcat.mechanism_views import conditioning_view as conditioning_view
from kinematics.views.meshcat.mechanism_views import parallel_view as parallel_view
from kinematics.views.meshcat.scene import Scene as Scene
from kinematics.views.meshcat.serial_views import NEAR_SINGULAR as NEAR_SINGULAR
from kinematics.views.meshcat.serial_views import default_pose as default_pose
from kinematics.views.meshcat.serial_views import scara_view as scara_view
from kinematics.views.meshcat.serial_views import serial_view as serial_view
from kinematics.views.meshcat.skeletons import SKELETON_STYLE as SKELETON_STYLE
from kinematics.views.meshcat.skeletons import skeleton_transforms as skeleton_transforms
from kinematics.views.meshcat.visuals import visual_model as visual_model

