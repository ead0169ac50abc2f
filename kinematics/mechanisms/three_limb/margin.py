"""The workspace margin of a three-limb closed-form family (3-[P2(US)], Delta): each working mode's
smallest constraint slack from the family's compiled scan, then their union, with the family's
exact columns attached for the column engine."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from kinematics.inputs import task_points
from kinematics.mechanisms.base import MarginFn


class ThreeLimbMargin:
    """points (N, 3) -> (N, len(cols) + 1) margins [m]: the modes `cols` of `scan_margin(points)`
    (N, 8), then their union (the maximum); `exact_columns` is what `column_volume` uses instead of
    sampling the columns."""

    def __init__(self, params: Any, cols: list[int], scan_margin: Callable[[np.ndarray], np.ndarray],
                 exact_columns: Any) -> None:
        self.params, self.cols = params, cols
        self._scan_margin = scan_margin
        self.exact_columns = exact_columns

    def __call__(self, points: np.ndarray) -> np.ndarray:
        m = self._scan_margin(task_points(points, 3))[:, self.cols]
        return np.concatenate([m, m.max(axis=1, keepdims=True)], axis=1)

    def sampled(self) -> MarginFn:
        """The same margin without exact columns (the engine then samples every column)."""
        def margin(points: np.ndarray) -> np.ndarray:
            return self(points)

        return margin


def column_buffers(columns: int, targets: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Zeroed outputs of an exact-columns kernel: lengths and errors (M, T) [m], interval ends
    (M, T), signatures (M,) and the inside extent (M, 2), empty as (+inf, -inf)."""
    zbox = np.empty((columns, 2))
    zbox[:, 0], zbox[:, 1] = np.inf, -np.inf
    return (np.zeros((columns, targets)), np.zeros((columns, targets)), np.zeros((columns, targets), np.int64),
            np.zeros(columns, np.int64), zbox)


__all__ = ["ThreeLimbMargin", "column_buffers"]
