"""The whole-system solver (`LoopBatch(solver="whole")`, `WholeSolver`): every unknown of each
branch at once (8 rows per target for the 3-[P2(US)]), from (1) a solved neighbour's end of that
branch (a cache of earlier batches, a coarse subset of the batch solved first), else (2) the atlas
configuration of the branch, then (3) starts built block by block (`blockwise`) where some but
not all branches were found. It is the reference path the tests hold the block solver to, and
10-15x slower; `from_robot` falls back on it where the equations do not split in dependency order.
"""

from __future__ import annotations

import numpy as np

from kinematics.generic.loop_batch.atlas import BranchSolutions, LoopAtlas
from kinematics.generic.loop_batch.compiled import TOL
from kinematics.generic.loop_batch.margins import LoopMargins
from kinematics.generic.loop_batch.warm import WARM_RADIUS_FACTOR, WarmStarts


class WholeSolver(LoopAtlas, LoopMargins, WarmStarts):
    """`ik` with every unknown of a branch at once (a part of `LoopBatch`)."""

    def _solve(self, p: np.ndarray, warm: bool,
               extra: tuple[np.ndarray, np.ndarray] | None = None) -> BranchSolutions:
        from scipy.spatial import cKDTree

        N, B, n = len(p), len(self.labels), self.n
        best_x = np.full((N, B, n), np.nan)
        best_d = np.full((N, B), np.inf)
        residual = np.full((N, B), np.inf)
        end_x = np.full((N, B, n), np.nan)  # where each slot's best start ended (root or least-squares point)
        counters = [0, 0]
        codes = (np.array(self.labels, dtype=np.int64) + 1) @ (3 ** np.arange(len(self.labels[0]), dtype=np.int64))
        code_slot = np.argsort(codes)
        codes_sorted = codes[code_slot]

        def attempt(idx: np.ndarray, slot: np.ndarray, x0: np.ndarray, iters: int) -> None:
            if not len(idx):
                return
            x, res, _ = self.newton(p[idx], x0, iters=iters)
            better = res < residual[idx, slot]
            order = np.argsort(-res[better])  # ties: the smallest residual is written last
            end_x[idx[better][order], slot[better][order]] = x[better][order]
            np.minimum.at(residual, (idx, slot), res)
            ok = res <= TOL
            if not ok.any():
                return
            i, x, slot = idx[ok], self.canonical(x[ok]), slot[ok]
            _, J, _ = self.evaluate(p[i], x)
            lab = self.label_of(J, x)
            # label -> slot through the labels' codes in base 3 (-1, 0, +1 -> 0, 1, 2)
            key = (lab.astype(np.int64) + 1) @ (3 ** np.arange(lab.shape[1], dtype=np.int64))
            target = np.full(len(key), -1)
            pos = np.searchsorted(codes_sorted, key)
            hit = (pos < len(codes_sorted)) & (codes_sorted[np.minimum(pos, len(codes_sorted) - 1)] == key)
            target[hit] = code_slot[pos[hit]]
            counters[0] += int(np.sum(target < 0))
            good = target >= 0
            i, x, target = i[good], x[good], target[good]
            d = self._distance_to_reference(x)
            # per (target, slot): the candidate nearest the reference beats the one in place
            order = np.lexsort((d, target, i))
            i, x, target, d = i[order], x[order], target[order], d[order]
            first = np.ones(len(i), dtype=bool)
            first[1:] = (i[1:] != i[:-1]) | (target[1:] != target[:-1])
            dup = ~first & ~np.all(np.abs(x[:, self.actuated] - np.repeat(x[first][:, self.actuated],
                                   np.diff(np.r_[np.flatnonzero(first), len(i)]), axis=0)) <= 1e-9, axis=1)
            counters[1] += int(np.sum(dup))
            i, x, target, d = i[first], x[first], target[first], d[first]
            better = d < best_d[i, target]
            i, x, target, d = i[better], x[better], target[better], d[better]
            best_d[i, target], best_x[i, target], end_x[i, target] = d, x, x
            residual[i, target] = 0.0

        # (1) neighbours (earlier batches, this batch's coarse subset): each slot from the same
        # slot's root or least-squares point there (continuation)
        tried = np.zeros((N, B), dtype=bool)
        sources = [self._nearest_cached(p, (B, n))] if warm else []
        if extra is not None and len(extra[0]):
            dist, j = cKDTree(extra[0]).query(p, distance_upper_bound=WARM_RADIUS_FACTOR * self.scale)
            sources.append((dist, np.where(np.isfinite(dist)[:, None, None], extra[1][np.minimum(j, len(extra[0]) - 1)],
                                           np.nan)))
        for dist, ends in sources:
            near = np.isfinite(dist)
            has = np.isfinite(ends[:, :, 0])
            idx, slot = np.nonzero(near[:, None] & has & ~np.isfinite(best_d))
            attempt(idx, slot, ends[idx, slot], 20)
            tried[idx, slot] = True
        # (2) the atlas configuration of each label not started from a neighbour
        idx, slot = np.nonzero(~tried & ~np.isfinite(best_d))
        attempt(idx, slot, self.atlas[slot], 40)
        # (3) block by block, where some but not all branches were found
        some = np.isfinite(best_d).any(axis=1) & ~np.isfinite(best_d).all(axis=1)
        idx, slot = np.nonzero(some[:, None] & ~np.isfinite(best_d))
        if self.restarts and len(idx):
            attempt(idx, slot, self.blockwise(p[idx], slot, np.random.default_rng(len(p))), 20)
        found = np.isfinite(best_d)
        residual = np.where(found, 0.0, np.where(np.isfinite(residual), residual, np.nan))
        margin = np.where(found, self.limit_margin(np.nan_to_num(best_x)),
                          -np.maximum(np.nan_to_num(residual, nan=1.0), 1e-300))
        return BranchSolutions(best_x, found, residual, margin, counters[0], counters[1], end_x)

    def blockwise(self, targets: np.ndarray, slot: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Starts for branch `slot` at each target, built block by block in the triangular order:
        each block's unknowns are solved from its own equations (the earlier blocks' unknowns
        held), from the atlas values of that branch and, for a labelling block that lands on the
        wrong sign, from `restarts` random values of its unknowns; the best candidate is kept."""
        x = np.array(self.atlas[slot], dtype=float)
        want = np.array(self.labels, dtype=np.int8)[slot]  # (R, L)
        lab_index = {b: k for k, b in enumerate(self.label_blocks)}
        R = len(x)
        for blk in self.blocks:
            if not blk.cols:
                continue
            rows = np.zeros(self._m, dtype=bool)
            rows[list(blk.rows)] = True
            free = np.zeros(self.n, dtype=bool)
            free[list(blk.cols)] = True
            k = lab_index.get(blk)
            tries = 1 + (self.restarts if k is not None else 0)
            starts = np.repeat(x[None], tries, axis=0)  # (tries, R, n)
            if tries > 1:
                rnd = self.seed_configurations(R * (tries - 1), rng).reshape(tries - 1, R, self.n)
                starts[1:, :, list(blk.cols)] = rnd[:, :, list(blk.cols)]
            flat = starts.reshape(-1, self.n)
            tt = np.tile(targets, (tries, 1))
            y, res, _ = self.newton(tt, flat, iters=30, free=free, rows=rows)
            y = self.canonical(y)
            score = res.copy()
            if k is not None:
                _, J, _ = self.evaluate(tt, y)
                sign = self.label_of(J, y)[:, list(self.label_blocks).index(blk)]
                score = np.where(sign == np.tile(want[:, k], tries), score, score + 10.0)
            score = score.reshape(tries, R)
            best = np.argmin(score, axis=0)
            x = y.reshape(tries, R, self.n)[best, np.arange(R)]
        return x
