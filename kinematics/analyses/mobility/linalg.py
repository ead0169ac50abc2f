"""Rank, column space and null space with one tolerance rule, for the mobility analyses."""

from __future__ import annotations

import numpy as np

RANK_RTOL = 1e-9
"""Rank tolerance of every decomposition here: singular values <= RANK_RTOL * the largest count
as zero. Reported with the singular-value gap so that a near-singular pose is visible."""


def rank_of(s: np.ndarray, rtol: float = RANK_RTOL) -> int:
    return int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0


def orth(A: np.ndarray, rtol: float = RANK_RTOL, scale: float | None = None) -> np.ndarray:
    """Orthonormal basis (columns) of the column space of A; singular values count when above
    rtol * scale (default: A's largest, which is wrong for a residual that should vanish)."""
    if A.size == 0:
        return np.zeros((A.shape[0], 0))
    U, s, _ = np.linalg.svd(A, full_matrices=False)
    ref = s[0] if scale is None else scale
    return U[:, : int(np.sum(s > rtol * ref))]


def null(A: np.ndarray, rtol: float = RANK_RTOL, scale: float | None = None) -> np.ndarray:
    """Orthonormal basis (columns) of the null space of A (n columns -> n - rank vectors)."""
    n = A.shape[1]
    if A.shape[0] == 0 or not np.any(A):
        return np.eye(n)
    _, s, Vt = np.linalg.svd(A, full_matrices=True)
    ref = s[0] if scale is None else scale
    r = int(np.sum(s > rtol * ref))
    return Vt[r:].T

