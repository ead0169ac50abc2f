"""Any URDF + loop sidecar without closed forms, as a mechanism."""

from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop

__all__ = ["GenericClosedLoop"]
