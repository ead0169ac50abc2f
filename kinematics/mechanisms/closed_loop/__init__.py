"""Any URDF + loop sidecar without closed forms, as a mechanism; its closed poses and constrained
Jacobians for reports."""

from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop as GenericClosedLoop
from kinematics.mechanisms.closed_loop.poses import ClosedPose as ClosedPose
from kinematics.mechanisms.closed_loop.poses import closed_pose as closed_pose
from kinematics.mechanisms.closed_loop.poses import constrained_jacobian as constrained_jacobian
from kinematics.mechanisms.closed_loop.poses import held_frames as held_frames

