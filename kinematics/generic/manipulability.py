"""Manipulability ellipsoids (Yoshikawa 1985) of any Jacobian, single or stacked.

For a task Jacobian J (m x n) the ellipsoid {J q_dot : |q_dot| <= 1} has principal radii equal to
the singular values of J, i.e. r_k = sqrt(lambda_k(J J^T)) [m] for translational rows, along the
eigenvectors of J J^T. Conventions:

* radii are sorted ascending (the smallest, the distance-to-singularity measure, comes first);
  with more task rows than joints the missing radii are 0;
* each direction is a unit vector whose largest-magnitude component is positive (first such
  component on ties), so results are deterministic;
* Yoshikawa's index w = sqrt(det(J J^T)) = product of the radii;
* condition number k = r_max / r_min (inf when r_min = 0);
* `singular` is r_min <= SINGULAR_RTOL * r_max: scale-free, so it means the same for a 0.7 m arm
  and a 7 m one. 1e-8 is where inverting J loses half of double precision's digits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.errors import InvalidInputError

SINGULAR_RTOL = 1e-8
"""Relative tolerance of the singularity flag: r_min <= SINGULAR_RTOL * r_max."""


@dataclass(frozen=True)
class Ellipsoid:
    """Manipulability ellipsoid of one Jacobian.

    Attributes:
        radii: (m,) principal radii, ascending [task units per unit joint rate].
        directions: (m, m) row k is the unit direction of radius k.
        yoshikawa: w = sqrt(det(J J^T)).
        condition_number: r_max / r_min (inf when singular to machine precision).
        singular: r_min <= rtol * r_max.
    """

    radii: np.ndarray
    directions: np.ndarray
    yoshikawa: float
    condition_number: float
    singular: bool


def _canonical_signs(directions: np.ndarray) -> np.ndarray:
    """Flip unit vectors (last axis) so that their largest-magnitude component is positive."""
    idx = np.argmax(np.abs(directions), axis=-1)[..., None]
    sign = np.sign(np.take_along_axis(directions, idx, axis=-1))
    sign[sign == 0] = 1.0
    return directions * sign


def _check_jacobian(J: np.ndarray) -> np.ndarray:
    J = np.asarray(J, dtype=float)
    if J.ndim < 2 or 0 in J.shape[-2:]:
        raise InvalidInputError("jacobian", f"expected a matrix (or a stack of matrices), got shape {J.shape}")
    if not np.all(np.isfinite(J)):
        raise InvalidInputError("jacobian", "contains NaN or inf")
    return J


def ellipsoid(J: np.ndarray, rtol: float = SINGULAR_RTOL) -> Ellipsoid:
    """Manipulability ellipsoid of a single m x n Jacobian (via the SVD, any m and n)."""
    J = _check_jacobian(J)
    if J.ndim != 2:
        raise InvalidInputError("jacobian", f"expected one matrix, got shape {J.shape}; use ellipsoids()")
    m, n = J.shape
    U, s, _ = np.linalg.svd(J, full_matrices=True)
    radii = np.zeros(m)
    radii[: min(m, n)] = s
    order = np.argsort(radii, kind="stable")
    radii = radii[order]
    directions = _canonical_signs(U[:, order].T)
    r_min, r_max = radii[0], radii[-1]
    cond = float(r_max / r_min) if r_min > 0 else float("inf")
    return Ellipsoid(
        radii=radii,
        directions=directions,
        yoshikawa=float(np.prod(radii)),
        condition_number=cond,
        singular=bool(r_min <= rtol * r_max),
    )


@dataclass(frozen=True)
class Ellipses:
    """Stacked planar (2 x 2) ellipses; every field has the stack's leading shape `S`.

    Attributes:
        radii: S + (2,) ascending radii.
        directions: S + (2, 2) unit directions, `directions[..., k, :]` for radius k.
        yoshikawa: S, |det J|.
        condition_number: S, r_max / r_min (inf where r_min = 0).
        singular: S, r_min <= rtol * r_max.
    """

    radii: np.ndarray
    directions: np.ndarray
    yoshikawa: np.ndarray
    condition_number: np.ndarray
    singular: np.ndarray


def ellipses_2x2(J: np.ndarray, rtol: float = SINGULAR_RTOL) -> Ellipses:
    """Closed-form manipulability ellipses of a stack of 2 x 2 Jacobians, shape S + (2, 2).

    With J J^T = [[a, b], [b, c]]: r_max^2 = (a + c)/2 + sqrt(((a - c)/2)^2 + b^2) and
    r_min^2 = det(J)^2 / r_max^2 (no cancellation near a singularity). The major direction is
    the eigenvector (b, r_max^2 - a) or (r_max^2 - c, b), whichever is longer.
    """
    J = _check_jacobian(J)
    if J.shape[-2:] != (2, 2):
        raise InvalidInputError("jacobian", f"expected 2 x 2 matrices, got shape {J.shape}")
    j11, j12, j21, j22 = J[..., 0, 0], J[..., 0, 1], J[..., 1, 0], J[..., 1, 1]
    return _ellipses_from_entries(j11, j12, j21, j22, j11 * j22 - j12 * j21, rtol)


def _ellipses_from_entries(
    j11: np.ndarray, j12: np.ndarray, j21: np.ndarray, j22: np.ndarray, det: np.ndarray, rtol: float
) -> Ellipses:
    a = j11 * j11 + j12 * j12
    b = j11 * j21 + j12 * j22
    c = j21 * j21 + j22 * j22
    half_diff = 0.5 * (a - c)
    lam_max = 0.5 * (a + c) + np.sqrt(half_diff * half_diff + b * b)
    det2 = det * det
    with np.errstate(divide="ignore", invalid="ignore"):
        lam_min = np.where(lam_max > 0, det2 / lam_max, 0.0)
    r_max = np.sqrt(lam_max)
    r_min = np.sqrt(lam_min)
    # Major eigenvector: pick the better-conditioned of the two equivalent expressions.
    e1x, e1y = b, lam_max - a
    e2x, e2y = lam_max - c, b
    n1 = e1x * e1x + e1y * e1y
    n2 = e2x * e2x + e2y * e2y
    use1 = n1 >= n2
    ux = np.where(use1, e1x, e2x)
    uy = np.where(use1, e1y, e2y)
    norm = np.sqrt(np.maximum(n1, n2))
    degenerate = norm == 0  # isotropic (a == c, b == 0): any direction; take x
    with np.errstate(divide="ignore", invalid="ignore"):
        ux = np.where(degenerate, 1.0, ux / norm)
        uy = np.where(degenerate, 0.0, uy / norm)
    major = _canonical_signs(np.stack([ux, uy], axis=-1))
    minor = _canonical_signs(np.stack([-major[..., 1], major[..., 0]], axis=-1))
    with np.errstate(divide="ignore"):
        cond = np.where(r_min > 0, r_max / np.where(r_min > 0, r_min, 1.0), np.inf)
    return Ellipses(
        radii=np.stack([r_min, r_max], axis=-1),
        directions=np.stack([minor, major], axis=-2),
        yoshikawa=np.abs(det),
        condition_number=cond,
        singular=r_min <= rtol * r_max,
    )
