"""Compiled task-space cell kernels: marking the cells within or meeting balls, the position
Jacobian's singular values and a box's image-ball radius (`radii` exposes them), the per-cell
dexterity aggregation; and the cells' measures and the reach ball's cells."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from kinematics.analyses.serial_workspace.result import Mode
from kinematics.errors import InvalidInputError


@njit(cache=True)
def _span(c, r, o, h, n, inner):  # pragma: no cover - compiled
    """Cells [o + jh, o + (j+1)h] of a row of n within distance r of coordinate c: all of the
    cell within r (inner) or any of it (not inner). Returns (first, last), last < first if none."""
    if inner:
        lo = math.ceil((c - r - o) / h)
        hi = math.floor((c + r - o) / h) - 1
    else:
        lo = math.ceil((c - r - o) / h) - 1
        hi = math.floor((c + r - o) / h)
    return max(lo, 0), min(hi, n - 1)


@njit(cache=True)
def _rows(y, rad, origin, h, d, diff, inner, which):  # pragma: no cover - compiled
    """For each ball B(y_k, rad_k), k in `which`, add +1 / -1 at the ends of the row spans of the
    cells wholly inside it (inner) or meeting it (not inner) in `diff`, the grid with one more
    entry along its last axis (2-D: axis 1); `_apply` turns the sums into marks. A ball costs
    one entry per row it crosses, not one per cell."""
    nx = diff.shape[0]
    ny = diff.shape[1] - 1 if d == 2 else diff.shape[1]
    nz = diff.shape[2] - 1
    for k in which:
        r = rad[k]
        if not r > 0.0 and (inner or r != 0.0):  # a point still touches its own cell
            continue
        i0, i1 = _span(y[k, 0], r, origin[0], h, nx, False)
        for i in range(i0, i1 + 1):
            x0 = origin[0] + i * h - y[k, 0]
            dx = max(abs(x0), abs(x0 + h)) if inner else max(0.0, x0, -(x0 + h))
            ry2 = r * r - dx * dx
            if ry2 < 0.0:
                continue
            ry = math.sqrt(ry2)
            if d == 2:
                j0, j1 = _span(y[k, 1], ry, origin[1], h, ny, inner)
                if j1 >= j0:
                    diff[i, j0, 0] += 1
                    diff[i, j1 + 1, 0] -= 1
                continue
            j0, j1 = _span(y[k, 1], ry, origin[1], h, ny, False)
            for j in range(j0, j1 + 1):
                y0 = origin[1] + j * h - y[k, 1]
                dy = max(abs(y0), abs(y0 + h)) if inner else max(0.0, y0, -(y0 + h))
                rz2 = ry2 - dy * dy
                if rz2 < 0.0:
                    continue
                m0, m1 = _span(y[k, 2], math.sqrt(rz2), origin[2], h, nz, inner)
                if m1 >= m0:
                    diff[i, j, m0] += 1
                    diff[i, j, m1 + 1] -= 1


@njit(cache=True)
def _apply(diff, grid, d):  # pragma: no cover - compiled
    """Set the grid cells whose running sum of `diff` along the rows is positive; clear `diff`."""
    nx, ny, nz = grid.shape
    for i in range(nx):
        if d == 2:
            acc = 0
            for j in range(ny):
                acc += diff[i, j, 0]
                diff[i, j, 0] = 0
                if acc > 0:
                    grid[i, j, 0] = 1
            diff[i, ny, 0] = 0
            continue
        for j in range(ny):
            acc = 0
            for m in range(nz):
                acc += diff[i, j, m]
                diff[i, j, m] = 0
                if acc > 0:
                    grid[i, j, m] = 1
            diff[i, j, nz] = 0


BATCH_ROWS = 4
"""Balls are marked in batches of about BATCH_ROWS x the grid's cells in rows (at least
MIN_BATCH_ROWS) before the grid's distance transform is taken again to drop the balls that can
add nothing: a transform costs about as much as marking that many rows."""

MIN_BATCH_ROWS = 1 << 21


def _mark(y: np.ndarray, rad: np.ndarray, origin: np.ndarray, h: float, d: int, grid: np.ndarray, inner: bool,
          care: np.ndarray | None) -> None:
    """Set the cells wholly inside (inner) or meeting (not inner) the closed balls B(y_k, rad_k).

    When the balls' rows exceed a batch (`BATCH_ROWS`), the largest are marked first, and a ball
    is dropped once no unmarked cell of `care` (None: every cell) lies within its radius: the
    distance transform of those cells, taken after each batch, bounds the distance from the
    ball's centre to them (less a cell diagonal). Outside `care` the marks are then a subset of
    the balls' cells; inside it they are exactly those cells."""
    shape = list(grid.shape)
    shape[d - 1] += 1
    diff = np.zeros(shape, np.int32 if len(y) < np.iinfo(np.int32).max else np.int64)  # a row's sum <= len(y)
    rows = (2 * np.maximum(rad, 0.0) / h + 2) ** (d - 1)  # rows a ball crosses, at most
    batch = max(BATCH_ROWS * grid.size, MIN_BATCH_ROWS)
    if rows.sum() <= batch:
        _rows(y, rad, origin, h, d, diff, inner, np.arange(len(y)))
        _apply(diff, grid, d)
        return
    from scipy.ndimage import distance_transform_edt

    cell = np.floor((y[:, :d] - origin[:d]) / h)
    centre_in = np.all((cell >= 0) & (cell < np.array(grid.shape[:d])), axis=1)
    cell = np.clip(cell, 0, np.array(grid.shape[:d]) - 1).astype(np.int64)
    todo = np.argsort(-rad, kind="stable")
    while len(todo):
        take = max(1, int(np.searchsorted(np.cumsum(rows[todo]), batch)))
        _rows(y, rad, origin, h, d, diff, inner, todo[:take])
        _apply(diff, grid, d)
        todo = todo[take:]
        open_ = grid == 0 if care is None else (grid == 0) & (care == 1)
        if not open_.any():
            return
        dist = distance_transform_edt(~open_ if d == 3 else ~open_[:, :, 0])
        c = cell[todo]
        at = dist[tuple(c.T)] if d == 3 else dist[c[:, 0], c[:, 1]]
        # |p - y| >= (dist - sqrt(d)) h for every point p of an open cell (centre-to-centre
        # distance less two half diagonals): such balls meet no open cell.
        todo = todo[~centre_in[todo] | ((at - math.sqrt(d)) * h <= rad[todo] * (1 + 1e-9))]


def mark_within(y: np.ndarray, rad: np.ndarray, origin: np.ndarray, h: float, d: int, grid: np.ndarray,
                care: np.ndarray | None = None) -> None:
    """Set grid cells lying wholly inside the ball B(y_k, rad_k) (outside `care`, maybe fewer)."""
    _mark(y, rad, origin, h, d, grid, True, care)


def mark_touching(y: np.ndarray, rad: np.ndarray, origin: np.ndarray, h: float, d: int, grid: np.ndarray,
                  care: np.ndarray | None = None) -> None:
    """Set grid cells that meet the closed ball B(y_k, rad_k) (outside `care`, maybe fewer)."""
    _mark(y, rad, origin, h, d, grid, False, care)


@njit(cache=True)
def jacobian_stats(J, Ja, half, B, sig_min, sig_max, yosh, eps):  # pragma: no cover - compiled
    """Per configuration: singular values of the m x k position Jacobian J (m = 2 or 3) and the
    image-ball radius eps = sum_i |Ja_i| d_i + sum_ij B_ij d_i d_j / 2 of its box.

    det(J J^T) and e2 (sum of its 2 x 2 principal minors) come from Cauchy-Binet as sums of
    squared minors of J (no cancellation); lambda_max from the trigonometric solution (m = 3) or
    the quadratic (m = 2); lambda_min = det / (product of the others), accurate near a singularity."""
    N, m, k = J.shape
    for t in range(N):
        tr = 0.0
        for r in range(m):
            for c in range(k):
                tr += J[t, r, c] * J[t, r, c]
        if m == 2:
            det = 0.0
            for i in range(k):
                for j in range(i + 1, k):
                    mnr = J[t, 0, i] * J[t, 1, j] - J[t, 0, j] * J[t, 1, i]
                    det += mnr * mnr
            a = 0.0
            b = 0.0
            c2 = 0.0
            for c in range(k):
                a += J[t, 0, c] * J[t, 0, c]
                b += J[t, 0, c] * J[t, 1, c]
                c2 += J[t, 1, c] * J[t, 1, c]
            lmax = 0.5 * (a + c2) + math.sqrt(0.25 * (a - c2) ** 2 + b * b)
            lmin = det / lmax if lmax > 0 else 0.0
        else:
            det = 0.0
            for i in range(k):
                for j in range(i + 1, k):
                    for l in range(j + 1, k):
                        mnr = (J[t, 0, i] * (J[t, 1, j] * J[t, 2, l] - J[t, 1, l] * J[t, 2, j])
                               - J[t, 0, j] * (J[t, 1, i] * J[t, 2, l] - J[t, 1, l] * J[t, 2, i])
                               + J[t, 0, l] * (J[t, 1, i] * J[t, 2, j] - J[t, 1, j] * J[t, 2, i]))
                        det += mnr * mnr
            e2 = 0.0
            for r1 in range(3):
                for r2 in range(r1 + 1, 3):
                    for i in range(k):
                        for j in range(i + 1, k):
                            mnr = J[t, r1, i] * J[t, r2, j] - J[t, r1, j] * J[t, r2, i]
                            e2 += mnr * mnr
            A = np.zeros((3, 3))
            for r1 in range(3):
                for r2 in range(3):
                    acc = 0.0
                    for c in range(k):
                        acc += J[t, r1, c] * J[t, r2, c]
                    A[r1, r2] = acc
            q = tr / 3.0
            p1 = A[0, 1] ** 2 + A[0, 2] ** 2 + A[1, 2] ** 2
            p2 = (A[0, 0] - q) ** 2 + (A[1, 1] - q) ** 2 + (A[2, 2] - q) ** 2 + 2 * p1
            pp = math.sqrt(p2 / 6.0)
            if pp > 0:
                C = (A - q * np.eye(3)) / pp
                hdet = 0.5 * (C[0, 0] * (C[1, 1] * C[2, 2] - C[1, 2] * C[2, 1])
                              - C[0, 1] * (C[1, 0] * C[2, 2] - C[1, 2] * C[2, 0])
                              + C[0, 2] * (C[1, 0] * C[2, 1] - C[1, 1] * C[2, 0]))
                phi = math.acos(min(1.0, max(-1.0, hdet))) / 3.0
                lmax = q + 2 * pp * math.cos(phi)
                l1 = q + 2 * pp * math.cos(phi + 2 * math.pi / 3)
            else:
                lmax = q
                l1 = q
            l1 = max(l1, 0.0)
            rest = e2 - l1 * (tr - l1)  # product of the two larger eigenvalues
            lmin = det / rest if rest > 0 else 0.0
        # det and e2 are sums of squares (relative error ~ k eps) and so is lambda_min = det / rest:
        # a relative margin of 1e-10 keeps sigma_min from being overstated by rounding.
        lmin = max(lmin * (1.0 - 1e-10), 0.0)
        sig_min[t] = math.sqrt(lmin)
        sig_max[t] = math.sqrt(max(lmax, 0.0))
        yosh[t] = math.sqrt(det)
        e = 0.0
        h2 = 0.0
        for c in range(Ja.shape[2]):
            n2 = 0.0
            for r in range(m):
                n2 += Ja[t, r, c] * Ja[t, r, c]
            e += math.sqrt(n2) * half[t, c]
            for c2 in range(Ja.shape[2]):
                h2 += half[t, c] * B[c, c2] * half[t, c2]
        eps[t] = e + 0.5 * h2


def radii(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smallest and largest singular values and Yoshikawa's index of a stack of 2 x k or 3 x k
    position Jacobians (N, m, k), by the kernel the workspace uses (sigma_min is lowered by a
    relative 5e-11 against rounding, never raised).

    Returns:
        sigma_min, sigma_max [m/rad], w = sqrt(det(J J^T)), each (N,).
    """
    J = np.ascontiguousarray(J, dtype=float)
    if J.ndim != 3 or J.shape[1] not in (2, 3) or J.shape[2] < J.shape[1]:
        raise InvalidInputError("jacobian", f"expected (N, 2 or 3, k >= rows), got shape {J.shape}")
    out = [np.empty(len(J)) for _ in range(4)]
    jacobian_stats(J, J, np.zeros((len(J), J.shape[2])), np.zeros((J.shape[2], J.shape[2])), *out)
    return out[0], out[1], out[2]


@njit(cache=True)
def aggregate(idx, w, cond, rmin, gw, gc, gr):  # pragma: no cover - compiled
    for k in range(idx.shape[0]):
        i, j, m = idx[k, 0], idx[k, 1], idx[k, 2]
        if not gw[i, j, m] >= w[k]:
            gw[i, j, m] = w[k]
        if not gc[i, j, m] <= cond[k]:
            gc[i, j, m] = cond[k]
        if not gr[i, j, m] >= rmin[k]:
            gr[i, j, m] = rmin[k]


def meets_ball(origin: np.ndarray, h: float, shape3: tuple[int, ...], d: int, centre: np.ndarray,
                radius: float) -> np.ndarray:
    """uint8 grid: 1 where the cell meets the closed ball B(centre, radius)."""
    gap2 = np.zeros(shape3)
    for a in range(d):
        lo = origin[a] + np.arange(shape3[a]) * h - centre[a]
        g = np.maximum(0.0, np.maximum(lo, -(lo + h))) ** 2
        shape = [1, 1, 1]
        shape[a] = shape3[a]
        gap2 = gap2 + g.reshape(shape)
    return (gap2 <= radius * radius).astype(np.uint8)



def cell_measure(mode: Mode, origin: np.ndarray, h: float, shape3: tuple[int, ...]) -> np.ndarray:
    """Measure of each cell: h^2 (planar), h^3 (spatial), 2 pi rho_c h^2 (revolved: the cell's
    ring, exact since the grid starts at rho = 0)."""
    if mode == "planar":
        return np.full(shape3, h * h)
    if mode == "spatial":
        return np.full(shape3, h**3)
    rho_c = origin[0] + (np.arange(shape3[0]) + 0.5) * h
    return np.broadcast_to((2 * math.pi * rho_c * h * h)[:, None, None], shape3).copy()
