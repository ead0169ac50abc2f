"""Closed forms shared by the three-limb translational parallel robots (the 3-[P2(US)], the
Delta): working-mode labels (one IK root per limb), assembly modes, and forward kinematics as
the intersection of three spheres."""

from __future__ import annotations

import itertools
from typing import NamedTuple

import numpy as np

from kinematics.errors import UnknownModeError

MODES: tuple[str, ...] = tuple("".join(m) for m in itertools.product("+-", repeat=3))
"""The 8 working modes, in a fixed order: "+++", "++-", "+-+", ..., "---"."""

ASSEMBLY_MODES: tuple[str, ...] = ("below", "above")
"""FK assembly modes: the platform below or above the plane of the three sphere centres."""


BOUNDARY_TOL = 1e-12
"""IK discriminants (and FK's h^2) down to -BOUNDARY_TOL * L^2 count as zero: exactly on a
reach boundary (a type I pose) rounding leaves them at +/-1e-17 m^2."""

ACTUATOR_TOL = 1e-12
"""[m or rad] An actuator value this close beyond an end of its range counts as within it: the IK
gives back an actuator value the FK was given on an end to a few ulp (~1e-16 for values of order
1), so fk then ik keeps such a pose within the limits; 1e-12 leaves a factor 1e4."""


def mode_index(mode: str) -> int:
    """Index of a working-mode label in MODES; raises UnknownModeError."""
    try:
        return MODES.index(mode)
    except ValueError:
        raise UnknownModeError(mode, MODES) from None


class FKResult(NamedTuple):
    """Both assembly modes for actuator values of shape S + (3,).

    Attributes:
        p: S + (2, 3) platform positions [m] per ASSEMBLY_MODES (NaN where none exists).
        exists: S, the three rod spheres meet.
        gap: S, how much longer the rods would have to be for the spheres to meet [m]: the
            centres' circumradius minus L where they do not meet (inf if the centres are
            collinear), 0 where they do.
    """

    p: np.ndarray
    exists: np.ndarray
    gap: np.ndarray


def intersect_spheres(c: np.ndarray, L: float) -> FKResult:
    """Both points at distance L [m] from three centres c, shape S + (3, 3) (row i: centre i).

    In the frame ex = (c2 - c1)/|c2 - c1|, ey in the plane towards c3, ez = +/-(ex x ey) turned
    to point up (ex x ey points down when the limbs are numbered clockwise), p = c1 + x ex + y ey
    -/+ h ez with x = D/2, y = (i^2 + j^2 - 2 i x)/(2 j), h = sqrt(L^2 - x^2 - y^2): "below" takes
    -h. c1 + x ex + y ey is the centres' circumcentre, R = sqrt(x^2 + y^2) their circumradius:
    the spheres meet iff L >= R, and `gap` = R - L is how much longer the rods would need to be.
    If the centres' plane is vertical (never for rails inclined below the horizontal) "below"
    and "above" are ex x ey's -/+ side.
    """
    c1, c2, c3 = c[..., 0, :], c[..., 1, :], c[..., 2, :]
    d12 = c2 - c1
    D = np.linalg.norm(d12, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ex = d12 / D[..., None]
        d13 = c3 - c1
        i = np.sum(ex * d13, axis=-1)
        ey_raw = d13 - i[..., None] * ex
        j = np.linalg.norm(ey_raw, axis=-1)
        ey = ey_raw / j[..., None]
        ez = np.cross(ex, ey)
        ez *= np.where(ez[..., 2:] < 0, -1.0, 1.0)  # up, whatever the limbs' numbering
        x = 0.5 * D
        y = (i * i + j * j - 2.0 * i * x) / (2.0 * j)
        h2 = L**2 - x * x - y * y
    exists = np.isfinite(h2) & (h2 >= -BOUNDARY_TOL * L**2)
    h = np.sqrt(np.where(exists, np.maximum(h2, 0.0), np.nan))
    base = c1 + x[..., None] * ex + y[..., None] * ey
    p = np.stack([base - h[..., None] * ez, base + h[..., None] * ez], axis=-2)
    with np.errstate(invalid="ignore"):
        short = np.hypot(x, y) - L  # circumradius - L; inf for collinear centres (j = 0)
    return FKResult(p, exists, np.where(exists, 0.0, np.where(np.isnan(short), np.inf, short)))
