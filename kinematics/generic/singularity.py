"""Gosselin-Angeles singularity types from two scale-free measures, shared by every mechanism.

iota_I in [0, 1] vanishes where the inverse kinematic map loses rank (an actuator velocity is
undetermined by the task velocity: type I), iota_II where locked actuators no longer hold the
task point (type II); both at once: type III.
"""

from __future__ import annotations

import numpy as np

SINGULAR_TOL = 1e-6
"""A pose is singular when iota_I or iota_II <= this. Both are cosines / unit-vector volumes;
1e-6 is ~6e-5 degrees from exact singularity, above the ~1e-8 floor that rounding leaves in
iota_I (which behaves like the square root of an IK discriminant)."""

SINGULARITY_TYPES = ("none", "type I", "type II", "type III")
"""Gosselin-Angeles labels, indexed by `classify`."""


def classify(iota_I: np.ndarray, iota_II: np.ndarray, tol: float = SINGULAR_TOL) -> np.ndarray:
    """Singularity type codes: 0 none, 1 type I, 2 type II, 3 type III (index SINGULARITY_TYPES)."""
    return (np.asarray(iota_I) <= tol).astype(np.int8) + 2 * (np.asarray(iota_II) <= tol).astype(np.int8)
