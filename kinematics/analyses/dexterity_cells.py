"""Dexterity per region: the samples of `kinematics.analyses.dexterity` binned on a coarse grid
over the bounding box, each cell's reached measure and mean indices with the same replicate error
bars as the global means.

Per cell C and replicate r: c_r the samples inside W in C, S_r the sum of an index over them. The
cell's mean index is sum S_r / sum c_r, with the ratio estimator's t half-width over the R
replicates (`ratio_errors`); its reached measure |W cap C| = box x mean(c_r / n) with the t
half-width of the replicate fractions. A cell some replicate leaves empty gets an infinite error
(a handful of points). The harmonic mean of kappa over a cell is 1 / (its mean 1/kappa): that is
the condition number the table reports (the arithmetic mean of kappa diverges at a singularity).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from kinematics.errors import InvalidInputError

MAX_CELLS = 1 << 18
"""Cells of a table at most (a table a user plots; each carries R x 4 sums)."""


@dataclass(frozen=True)
class CellGrid:
    """A grid of cubes of side `step` [m] from `origin` over a box: `shape` cells per axis."""

    origin: np.ndarray
    step: float
    shape: tuple[int, ...]

    @classmethod
    def over(cls, lo: np.ndarray, hi: np.ndarray, cells: int) -> CellGrid:
        """`cells` steps along the box's longest side (at least one cell per axis)."""
        if not (isinstance(cells, int) and cells >= 1):
            raise InvalidInputError("cells", f"must be a positive number of cells, got {cells!r}")
        lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        step = float(np.max(hi - lo)) / cells
        shape = tuple(max(1, math.ceil((b - a) / step - 1e-9)) for a, b in zip(lo, hi, strict=True))
        if math.prod(shape) > MAX_CELLS:
            raise InvalidInputError("cells", f"{math.prod(shape):,} cells is more than {MAX_CELLS:,}; use fewer")
        return cls(lo, step, shape)

    @property
    def size(self) -> int:
        return math.prod(self.shape)

    def flat_index(self, points: np.ndarray) -> np.ndarray:
        """(N,) flat cell index of points (N, d) inside the box."""
        k = np.floor((np.asarray(points) - self.origin) / self.step).astype(np.int64)
        k = np.clip(k, 0, np.array(self.shape) - 1)
        return np.ravel_multi_index(tuple(k.T), self.shape)


def ratio_errors(S: np.ndarray, c: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Columnwise pooled ratios sum S / sum c over replicates (R, M) and their t half-widths
    (NaN where c sums to 0; inf where a replicate has no point)."""
    R = len(c)
    tot = c.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        G = S.sum(axis=0) / tot
        resid = S - G * c
        se = np.sqrt((resid**2).sum(axis=0) / (R * (R - 1))) / c.mean(axis=0)
    err = np.where((c == 0).any(axis=0), np.inf, t * se)
    return np.where(tot > 0, G, np.nan), np.where(tot > 0, err, np.nan)


@dataclass(frozen=True)
class CellTable:
    """Per cell with samples inside: grid index, centre [m], reached measure and error [m^3 or
    m^2], mean 1/kappa, mean Yoshikawa index, mean smallest radius (each with its half-width) and
    the points inside (all replicates)."""

    grid: CellGrid
    index: np.ndarray
    volume: np.ndarray
    volume_error: np.ndarray
    gci: np.ndarray
    gci_error: np.ndarray
    yoshikawa: np.ndarray
    yoshikawa_error: np.ndarray
    radius: np.ndarray
    radius_error: np.ndarray
    points: np.ndarray

    @classmethod
    def from_sums(cls, grid: CellGrid, c: np.ndarray, sums: tuple[np.ndarray, np.ndarray, np.ndarray], n: int,
                  box: float, t: float) -> CellTable:
        """From per-replicate counts c (R, M) and index sums (R, M) each, n points per replicate."""
        R = len(c)
        keep = np.flatnonzero(c.sum(axis=0) > 0)
        c = c[:, keep]
        frac = c / n
        vol = box * frac.mean(axis=0)
        vol_err = box * t * frac.std(axis=0, ddof=1) / math.sqrt(R)
        means = [ratio_errors(S[:, keep], c, t) for S in sums]
        idx = np.stack(np.unravel_index(keep, grid.shape), axis=1) if len(keep) else np.zeros((0, len(grid.shape)), int)
        return cls(grid, idx, vol, vol_err, *means[0], *means[1], *means[2], c.sum(axis=0))

    def rows(self, planar: bool) -> list[dict[str, Any]]:
        """One JSON-ready dict per cell (non-finite numbers become None)."""
        key = "area_m2" if planar else "volume_m3"

        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        out = []
        for k in range(len(self.index)):
            g = float(self.gci[k])
            lo = self.grid.origin + self.index[k] * self.grid.step
            out.append({
                "index": self.index[k].tolist(), "lower": lo.tolist(), "upper": (lo + self.grid.step).tolist(),
                key: float(self.volume[k]), f"{key}_error": float(self.volume_error[k]),
                "gci": num(g), "gci_error": num(self.gci_error[k]),
                "kappa_harmonic_mean": num(1.0 / g) if g > 0 else None,
                "yoshikawa_mean": num(self.yoshikawa[k]), "yoshikawa_error": num(self.yoshikawa_error[k]),
                "smallest_radius_mean": num(self.radius[k]), "smallest_radius_error": num(self.radius_error[k]),
                "points_inside": int(self.points[k]),
            })
        return out
