"""The warm-start cache of the batched closed-loop solver: solved points and where each branch's (or
block slot's) start ended there, the next batches' starts (continuation: a neighbour's root, or
its least-squares point outside the workspace, is the best start for a nearby target).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinematics.generic.loop_batch.model import LoopModel

WARM_RADIUS_FACTOR = 0.1
"""A solved point warm-starts another when closer than this x `scale` [m]."""

CACHE_POINTS = 100_000
"""Solved points kept for warm starts (the most recent first)."""

RECENT_POINTS = 8192
"""Points added to the warm-start cache before its KD-tree is rebuilt (`WarmCache`)."""


class WarmCache:
    """Solved points and where their starts ended, for warm starts, in a ring of CACHE_POINTS +
    RECENT_POINTS rows: a KD-tree over the newest CACHE_POINTS at its last rebuild, and the rows
    written since (at most RECENT_POINTS, searched through a small tree of their own). The rows
    the next writes overwrite are never in the big tree, so it stays valid until it is rebuilt, and
    nothing but the new rows is copied: a small batch (a root refinement step) pays neither for a
    tree over every cached point nor for copying the cache."""

    def __init__(self, shape: tuple[int, ...]) -> None:
        self.shape = shape
        self.points = np.empty((0, 0))
        self.ends = np.empty((0,) + shape)
        self.head = 0  # the next row written
        self.count = 0  # rows holding a point
        self.fresh = 0  # rows written since the tree was built
        self.tree: Any = None
        self.tree_rows = np.empty(0, dtype=np.int64)

    def add(self, p: np.ndarray, end: np.ndarray) -> None:
        if not len(self.points):
            self.points = np.empty((CACHE_POINTS + RECENT_POINTS, p.shape[1]))
            self.ends = np.empty((CACHE_POINTS + RECENT_POINTS,) + self.shape)
        size = len(self.points)
        p, end = p[-size:], end[-size:]
        m = len(p)
        if self.fresh + m > RECENT_POINTS:
            # a batch past the fresh rows' room is written whole and the tree rebuilt once after it
            # (the rows it overwrites may be in the old tree, which nothing queries in between)
            self.tree = None
        rows = (self.head + np.arange(m)) % size
        self.points[rows], self.ends[rows] = p, end
        self.head = (self.head + m) % size
        self.fresh += m
        self.count = min(self.count + m, size)
        if self.tree is None and self.fresh > RECENT_POINTS:
            self._rebuild()

    def _rebuild(self) -> None:
        from scipy.spatial import cKDTree

        self.tree_rows = (self.head - 1 - np.arange(min(self.count, CACHE_POINTS))) % len(self.points)
        self.tree = cKDTree(self.points[self.tree_rows], balanced_tree=False, compact_nodes=False)
        self.fresh = 0

    def nearest(self, q: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """(distance (N,), ends (N, *shape)) of the nearest cached point within `radius` of each
        row of q (inf and NaN where none)."""
        from scipy.spatial import cKDTree

        dist = np.full(len(q), np.inf)
        ends = np.full((len(q),) + self.shape, np.nan)
        sources = [(self.tree, self.tree_rows)] if self.tree is not None else []
        if self.fresh:
            rows = (self.head - self.fresh + np.arange(self.fresh)) % len(self.points)
            sources.append((cKDTree(self.points[rows], balanced_tree=False, compact_nodes=False), rows))
        for tree, rows in sources:
            d, j = tree.query(q, distance_upper_bound=radius)
            better = d < dist
            dist[better], ends[better] = d[better], self.ends[rows[j[better]]]
        return dist, ends


class WarmStarts(LoopModel):
    """The cache of solved points for warm starts (a part of `LoopBatch`)."""

    def _remember(self, p: np.ndarray, end: np.ndarray) -> None:
        """Keep solved points and their ends for the next batches' warm starts (`WarmCache`)."""
        if self._warm is None or self._warm.shape != end.shape[1:]:
            self._warm = WarmCache(end.shape[1:])
        self._warm.add(p, end)

    def _nearest_cached(self, p: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """`WarmCache.nearest` within the continuation radius (none if nothing of `shape` is cached)."""
        if self._warm is None or self._warm.shape != shape:
            return np.full(len(p), np.inf), np.full((len(p),) + shape, np.nan)
        return self._warm.nearest(p, WARM_RADIUS_FACTOR * self.scale)

    def forget(self) -> None:
        """Drop the warm-start cache."""
        self._warm = None
