"""Any URDF + loop sidecar without closed forms, as a mechanism; its closed poses and constrained
Jacobians for reports."""

from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop
from kinematics.mechanisms.closed_loop.poses import ClosedPose, closed_pose, constrained_jacobian, held_frames

__all__ = ["ClosedPose", "GenericClosedLoop", "closed_pose", "constrained_jacobian", "held_frames"]
