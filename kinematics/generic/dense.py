"""Small dense linear algebra compiled for the batched solvers' inner loops (the closed-loop block
solver, the serial reachability search): systems of a few unknowns solved per point, where a call
into LAPACK would cost more than the arithmetic."""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True, inline="always")
def cholesky_solve(A, b, out):  # pragma: no cover - compiled
    """Solve A out = b for a symmetric positive definite A (n, n), overwriting A's lower triangle
    with its Cholesky factor L (A = L L^T), then L y = b and L^T out = y. Returns False (out
    undefined) where a pivot is not positive: A is not positive definite to working precision."""
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= A[j, k] * A[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        A[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = s / d
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= A[i, k] * out[k]
        out[i] = s / A[i, i]
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, n):
            s -= A[k, i] * out[k]
        out[i] = s / A[i, i]
    return True


__all__ = ["cholesky_solve"]
