"""Where collisions can bind: a grid pre-scan of every pair's signed distance inside the kinematic
workspace, and the cells it cannot clear.

`measure_collision_workspace` uses it three ways: the pairs negative at some grid point are the
binding pairs it measures alone; where no pair comes near contact in any cell, the collision-free
workspace is the kinematic one, measured by the mechanism's own margin (its exact columns where it
has them); otherwise the joined margin (`CollisionMargin`) evaluates the pair distances only in
the close cells, m_b = k_b elsewhere.

Pre-scan: a grid of `cells` points per axis over the box, spacing g = (hi - lo) / (cells - 1). In
branch b, at each grid point inside its kinematic workspace (k_b > 0), every pair's signed
distance d_p [m]. The largest change of d_p between two neighbouring inside points, per metre,
estimates its slope s_bp (including the steep parts next to the reach boundary, where the
inverse kinematics turn fast). A point is *close* when some pair has d_p < SAFETY s_bp |g|
(twice that on the workspace's boundary, a point with an outside neighbour): a pair that far from
contact at every corner of a cell, at its observed slope, cannot reach contact inside it. The cells
with a close corner, grown by one cell on every side, and the cells with no corner inside the
kinematic workspace (not seen: a part of the workspace thinner than the grid can cross them; the
distances are only ever evaluated inside the kinematic workspace, so these cost nothing where it
is absent), are where the distances are evaluated; a pair close nowhere, in no branch, never
binds in the box.

What this adds to the column engine's own caveats (`kinematics.analyses.columns`): the slopes are
observed on the grid, not bounded, so a pair that plunges into contact faster between two grid
points than anywhere the grid sees can be missed.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from kinematics.analyses.collisions import CollisionMargin
    from kinematics.analyses.serial_collisions import SerialCollisionMargin

SAFETY = 2.0
"""Factor on the observed slope x cell diagonal below which a pair distance keeps its cell."""


class Prescan:
    """The pre-scan (module docstring) of a collision margin over the box [lo, hi].

    `pair_of`: (P,) the pair each of the margin's distance columns stands for (a turn envelope's
    band pairs stand for their body's pair, `TurnEnvelope.original`), None: each column its own
    pair. `counts` and `active` are per pair (G of them: max(pair_of) + 1), a grid point counting
    once where several of a pair's columns are negative.

    Attributes:
        counts: (G,) grid points where each pair is negative inside some branch's kinematic workspace.
        inside: (B,) grid points inside each branch's kinematic workspace.
        close: (B, cells - 1, ...) per branch, the cells where collisions are looked for.
        near: (B, cells - 1, ...) the part of `close` where some pair comes near contact (grown).
        active: (G,) the pairs close somewhere.
        slopes: (B, P) each distance column's observed slope per branch [m/m] (+inf: nothing observed).
    """

    def __init__(self, margin: CollisionMargin | SerialCollisionMargin, lo: np.ndarray, hi: np.ndarray, cells: int,
                 pair_of: np.ndarray | None = None) -> None:
        d = len(lo)
        self.lo, self.hi, self.cells = np.asarray(lo, float), np.asarray(hi, float), cells
        self.spacing = (self.hi - self.lo) / (cells - 1)
        axes = [np.linspace(self.lo[k], self.hi[k], cells) for k in range(d)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
        shape = (cells,) * d
        B, P = len(margin.branches), len(margin.distances.kinds)
        group = np.arange(P) if pair_of is None else np.asarray(pair_of, dtype=np.int64)
        # (P, G) column k in pair group[k]: a boolean matrix product ORs each pair's columns
        members = np.eye(int(group.max()) + 1 if P else 0, dtype=bool)[group]
        G = members.shape[1]
        kin = margin.kinematic(pts)
        self.counts = np.zeros(G, dtype=np.int64)
        self.inside = np.zeros(B, dtype=np.int64)
        self.close = np.zeros((B,) + (cells - 1,) * d, dtype=bool)
        self.near = np.zeros_like(self.close)
        self.active = np.zeros(G, dtype=bool)
        self.slopes = np.full((B, P), np.inf)
        diagonal = float(np.linalg.norm(self.spacing))
        for b in range(B):
            inside = kin[:, b] > 0
            self.inside[b] = int(inside.sum())
            if not inside.any():
                continue
            dist = np.full((len(pts), P), np.inf)
            if P:
                dist[inside] = margin.branch_distances(pts, b, inside, signs=False)  # true distances: slopes
            self.counts += ((dist < 0) @ members).sum(axis=0)
            if not P:
                continue
            grid = np.where(inside[:, None], dist, np.nan).reshape(*shape, P)
            slope = self.slopes[b] = _slopes(grid, self.spacing)
            threshold = SAFETY * slope * diagonal  # (P,)
            boundary = _on_boundary(inside.reshape(shape))
            near = grid < np.where(boundary[..., None], 2.0 * threshold, threshold)
            self.active |= near.reshape(-1, P).any(axis=0) @ members
            # a cell with no corner inside the workspace was not seen: a part of the workspace
            # thinner than the grid (p2us-results' sliver above the base) can pass through it
            self.near[b] = _grow(_cells_with(np.asarray(near.any(axis=-1))))
            self.close[b] = self.near[b] | ~_cells_with(inside.reshape(shape))

    def cell_index(self, points: np.ndarray) -> tuple[np.ndarray, ...]:
        """Index arrays of the grid cell holding each point (N, d) (clipped to the grid)."""
        k = np.floor((np.asarray(points, float) - self.lo) / self.spacing).astype(np.int64)
        k = np.clip(k, 0, self.cells - 2)
        return tuple(k.T)

    def close_rows(self, b: int, base: np.ndarray, ax: int) -> np.ndarray:
        """(M, cells - 1) branch b's close cells along each column at base (M, 2) along axis ax
        (3-D grids)."""
        others = [k for k in range(3) if k != ax]
        idx = []
        for n, k in enumerate(others):
            i = np.floor((base[:, n] - self.lo[k]) / self.spacing[k]).astype(np.int64)
            idx.append(np.clip(i, 0, self.cells - 2))
        close = np.moveaxis(self.close[b], ax, -1)
        return np.ascontiguousarray(close[idx[0], idx[1]])


def _slopes(grid: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """(P,) the largest |change| per metre of each pair's distance between grid neighbours that
    are both inside (NaN outside); +inf for a pair with no such neighbours (nothing observed)."""
    d, P = grid.ndim - 1, grid.shape[-1]
    best = np.full(P, -np.inf)
    for k in range(d):
        diff = np.abs(np.diff(grid, axis=k)).reshape(-1, P) / spacing[k]  # NaN where an end is outside
        best = np.fmax(best, np.fmax.reduce(diff, axis=0, initial=-np.inf))  # fmax skips NaN
    return np.where(np.isfinite(best), best, np.inf)


def _on_boundary(inside: np.ndarray) -> np.ndarray:
    """Inside grid points with an outside neighbour along some axis (or on the grid's face)."""
    from scipy.ndimage import binary_erosion

    return inside & ~binary_erosion(inside, border_value=0)


def _cells_with(points: np.ndarray) -> np.ndarray:
    """Cells (one fewer per axis) with at least one marked corner."""
    d = points.ndim
    out = np.zeros(tuple(n - 1 for n in points.shape), dtype=bool)
    for corner in itertools.product((0, 1), repeat=d):
        out |= points[tuple(slice(c, c + n - 1) for c, n in zip(corner, points.shape, strict=True))]
    return out


def _grow(cells: np.ndarray) -> np.ndarray:
    """`cells` and every cell touching one (faces, edges, corners)."""
    from scipy.ndimage import binary_dilation

    if not cells.any():
        return cells
    return binary_dilation(cells, structure=np.ones((3,) * cells.ndim, dtype=bool))


__all__ = ["SAFETY", "Prescan"]
