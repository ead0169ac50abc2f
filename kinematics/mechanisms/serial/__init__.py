"""Any open-chain URDF as a mechanism (no closed forms: compiled batched kinematics)."""

from kinematics.mechanisms.serial.mechanism import SerialArm as SerialArm

