"""Joint-limit margins of the batched closed-loop solver (`LoopMargins`).

**Margins.** Per branch, the smallest joint-limit slack in metres (prismatic: the distance to the
limit; revolute: the angle times `scale`), over every joint with a finite range narrower than
2 pi; >= 0 inside. Where the branch has no solution, minus the least-squares residual [m] reached
from its best start (< 0; block by block: the largest over the blocks tried, a block skipped
because an earlier one has no root counting for nothing). The union is the largest branch margin.

The compiled slack of rows of joint values (`slack_kernel`) and the block solver's per-slot
results combined into branches with their margins (`assemble_kernel`) are here: they call nothing
in `compiled`.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit, prange

from kinematics.errors import InvalidInputError
from kinematics.generic.loop_batch.compiled import PRISMATIC
from kinematics.generic.loop_batch.structure import LoopStructure

LIMITS = ("all", "actuators")
"""Which joint limits the margins apply."""


@njit(cache=True, inline="always")
def _slack_row(x, lo, hi, use, unit, pairs, paired, centre):  # pragma: no cover - compiled
    """`LoopBatch.limit_margin` of one row of joint values."""
    best = np.inf
    for j in range(x.shape[0]):
        if use[j] and not paired[j]:
            best = min(best, min(x[j] - lo[j], hi[j] - x[j]) * unit[j])
    for q in range(pairs.shape[0]):
        j1, j2 = pairs[q, 0], pairs[q, 1]
        s1 = np.inf
        s2 = np.inf
        a2 = (x[j1] + math.pi - centre[j1] + math.pi) % (2 * math.pi) + centre[j1] - math.pi
        b2 = (math.pi - x[j2] - centre[j2] + math.pi) % (2 * math.pi) + centre[j2] - math.pi
        if use[j1]:
            s1 = min(s1, min(x[j1] - lo[j1], hi[j1] - x[j1]) * unit[j1])
            s2 = min(s2, min(a2 - lo[j1], hi[j1] - a2) * unit[j1])
        if use[j2]:
            s1 = min(s1, min(x[j2] - lo[j2], hi[j2] - x[j2]) * unit[j2])
            s2 = min(s2, min(b2 - lo[j2], hi[j2] - b2) * unit[j2])
        best = min(best, max(s1, s2))
    return best


@njit(cache=True, parallel=True)
def slack_kernel(x, lo, hi, use, unit, pairs, paired, centre, out):  # pragma: no cover - compiled
    for r in prange(x.shape[0]):
        out[r] = _slack_row(x[r], lo, hi, use, unit, pairs, paired, centre)


# serial: a few copies per branch and row, less than a parallel launch costs on the small batches of
# root refinement (10 ms of a 2-thread launch where the machine is busy)
@njit(cache=True)
def assemble_kernel(order, end, found, res, bslot, cols, ncol, lo, hi, use, unit, pairs, paired, centre,
                     x_out, end_out, ok_out, res_out, margin_out):  # pragma: no cover - compiled
    """The block solver's per-slot results combined into branches (`LoopBatch._ik_blocks`):
    joint values (NaN unless every block of the branch was found), ends, residuals (the largest of
    the blocks tried; an untried block's earlier block failed) and margins; slot row r is target
    order[r]."""
    N = end.shape[0]
    B, K = bslot.shape
    n = x_out.shape[2]
    for row in range(N):
        i = order[row]
        for b in range(B):
            ok = True
            r = 0.0
            for k in range(K):
                s = bslot[b, k]
                for c in range(ncol[k]):
                    x_out[i, b, cols[k, c]] = end[row, k, s, c]  # the root where found
                    end_out[i, b, cols[k, c]] = end[row, k, s, c]
                ok = ok and found[row, k, s]
                if np.isfinite(res[row, k, s]) and res[row, k, s] > r:
                    r = res[row, k, s]
            ok_out[i, b] = ok
            if ok:
                res_out[i, b] = 0.0
                margin_out[i, b] = _slack_row(x_out[i, b], lo, hi, use, unit, pairs, paired, centre)
            else:
                res_out[i, b] = r
                margin_out[i, b] = -max(r, 1e-300)
                for j in range(n):
                    x_out[i, b, j] = np.nan


class LoopMargins(LoopStructure):
    """Joint-limit margins of joint values (a part of `LoopBatch`)."""

    def limit_margin(self, x: np.ndarray, limits: str = "all") -> np.ndarray:
        """Smallest joint-limit slack [m] of joint values x (..., n): prismatic distance to the
        limit, revolute angle x `scale`; joints without binding limits are ignored.

        limits: "all" (every joint) or "actuators" (the actuated joints only)."""
        if limits not in LIMITS:
            from kinematics.errors import UnknownChoiceError

            raise UnknownChoiceError(limits, LIMITS)
        x = np.asarray(x, dtype=float)
        if x.shape[-1] != self.n:
            raise InvalidInputError("x", f"expected (..., {self.n}) joint values, got {x.shape}")
        flat = np.ascontiguousarray(x.reshape(-1, self.n))
        out = np.empty(len(flat))
        if len(flat):
            lo, hi, use, unit, pairs, paired, centre = self._slack_args(limits)
            slack_kernel(flat, lo, hi, use, unit, pairs, paired, centre, out)
        return out.reshape(x.shape[:-1])

    def _slack_args(self, limits: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                np.ndarray]:
        use = self.limited.copy()
        if limits == "actuators":
            use[self.passive] = False
        unit = np.where(self._g[1] == PRISMATIC, 1.0, self.scale)
        pairs = np.array(self.free_pairs, dtype=np.int64).reshape(-1, 2)
        paired = np.zeros(self.n, dtype=np.bool_)
        paired[pairs.ravel()] = True
        return (np.asarray(self.robot.lower, dtype=float), np.asarray(self.robot.upper, dtype=float), use, unit, pairs,
                paired, self._centre)

    @functools.cached_property
    def free_pairs(self) -> tuple[tuple[int, int], ...]:
        """Concurrent pairs that are not flippable but whose other representation changes only
        joints without binding limits below them (a universal joint carrying a platform through an
        Euler spherical joint): the margin takes the better of the two representations."""
        flippable = set(self.flippable_groups)
        out = []
        for grp in self.concurrent_groups:
            if len(grp) != 2 or grp in flippable:
                continue
            below = [j for j in range(self.n) if self._descends(j, grp[1]) and j != grp[1]]
            if not any(self.limited[j] for j in below):
                out.append((grp[0], grp[1]))
        return tuple(out)
