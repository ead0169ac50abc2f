"""The block solver (`LoopBatch(solver="blocks")`, the default; `BlockSolver`).

`ik` solves **block by block**: each block is a small model of its own (`block_models`: the
ancestors of its frames; for a closure of a translational mechanism with a 3D task the platform
placed at the target), with one *slot* per choice of the labels its held joints depend on, times
its own sign for a labelling block (3-[P2(US)], Delta: 2 slots per block, 12 small solves per
target instead of 8 of all 18 unknowns). A branch is the combination of the slots of its labels;
it exists where every block has a root in its slot.
Each slot is sought from (1) a solved neighbour's end of that slot (a cache of earlier batches
and, inside a batch, every 64th then every 8th point solved first: continuation, also through the
least-squares points of targets outside), else (2) the atlas configuration of that slot, which is
also tried where a neighbour's end stalled less than the continuation radius from closure (a
neighbour outside the workspace leaves its end at a fold, from which Newton can stall), then (3)
`restarts` quasi-random starts of the block's unknowns (its locked joints held at the slot's
angles) where another slot of the block's same assembly (locked joints' half-turn bits) was found
or the block holds joints of earlier blocks that closed and no neighbour says the slot is absent
(a start's last entry: the slot's outcome where it came from, `_Slots.record_outcome`; a neighbour
where it was tried and not found means no restarts). The restarts are points of a quasi-random
sequence from an index that the target's coordinates give (`compiled.restart_base`), the same in
any batch; a slot still missing after them whose start closed on the block's root of the other
sign in its assembly gets up to RESTART_ROUNDS x `restarts` (its roots exist there in general:
the audit's five-bar point lost an elbow where 8 restarts all closed on the other one). Before the
restarts, a slot whose best start stalled next to closure, no slot of its assembly found, is
started from the roots its fold model predicts (`compiled.fold_roots`); where the model predicts
none and the target's warm starts came from a point within FOLD_SOURCE x the continuation radius
(a root refinement's probes, `source` of `_solve_slots`), that verdict replaces the restarts.
Blocks are solved in a dependency order, the smallest first; a slot that no live branch needs is skipped, so a target that one limb cannot
reach costs that limb's solves only. A block that later blocks hold values of is solved to
TOL / 100, so that an over-determined block built on it (a second rod) can still close to TOL.
A block with a spherical joint behind a 6D closure (`BlockModel.cuts`) is solved with the point
closure at the joint's centre, the joint's angles written after each solve in closed form
(`spheres`); its cold starts that stall are solved again as the whole block (`_retry_whole`).
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np

from kinematics import jit
from kinematics.generic.loop_batch.atlas import BranchSolutions, LoopAtlas
from kinematics.generic.loop_batch.compiled import TOL, block_kernel, eval_kernel, pack
from kinematics.generic.loop_batch.margins import LoopMargins, assemble_kernel
from kinematics.generic.loop_batch.spheres import sphere_angles, wrap
from kinematics.generic.loop_batch.structure import BlockModel
from kinematics.generic.loop_batch.warm import WARM_RADIUS_FACTOR, WarmStarts


class _Slots(NamedTuple):
    """The block solver's per-slot results (`LoopBatch._solve_slots`, `block_kernel`)."""

    found: np.ndarray  # (N, K, S)
    dist: np.ndarray  # (N, K, S) distance to the reference of the kept root
    res: np.ndarray  # (N, K, S) best residual of the starts aimed at the slot (inf: not tried; 0: found)
    end: np.ndarray  # (N, K, S, cmax + 1) each block's unknowns per slot: its kept root where found, else
    # where the slot's best start ended; then the slot's outcome (`_outcome`: 1 found, 0 tried and not
    # found, NaN not tried), which a neighbour's start carries to the kernel's restart rule
    counts: np.ndarray  # (N, 2) unlabelled roots, conflicts

    @classmethod
    def empty(cls, N: int, K: int, S: int, cmax: int) -> _Slots:
        return cls(np.zeros((N, K, S), dtype=np.bool_), np.full((N, K, S), np.inf),
                   np.full((N, K, S), np.inf), np.full((N, K, S, cmax + 1), np.nan), np.zeros((N, 2), dtype=np.int64))

    def record_outcome(self) -> None:
        """Write each slot's outcome into the last entry of `end` (1 found, 0 tried and not found, NaN
        not tried)."""
        self.end[..., -1] = np.where(self.found, 1.0, np.where(np.isfinite(self.res), 0.0, np.nan))


class BlockSolver(LoopAtlas, LoopMargins, WarmStarts):
    """`ik` block by block (a part of `LoopBatch`)."""

    @functools.cached_property
    def _block_tables(self) -> dict[str, Any]:
        """The block solver's packed arrays (`block_kernel`): per block its slots (one per choice
        of the labels it depends on, times its own sign for a labelling block), the slot each
        branch uses, the starts, and the sub-model indices padded to the largest block. Blocks with
        spherical triples in closed form (`BlockModel.cuts`) where their roots' labels follow from
        the reduced block's (`_cut_signs`); else every block whole."""
        tables = self._tables(self.block_models)
        if tables is None:
            self.spheres = False
            self.__dict__.pop("block_models", None)
            tables = self._tables(self.block_models)
        assert tables is not None  # without cuts every root's slot is its label's
        if any(bm.cuts for bm in self.block_models):
            tables["whole"] = self._tables(self.sub_models(False))
        return tables

    def _cut_signs(self, models: tuple[BlockModel, ...]) -> list[int] | None:
        """Per block, the sign s with full label = s x the reduced block's (its determinant times
        sign(cos) of its middle angles, as `block_kernel` computes it), read at every atlas pose:
        1 for a block without cuts or without a label; None where the atlas poses disagree or a
        reduced block is singular there (the cut is then not used)."""
        out = []
        for bm in models:
            if not bm.cuts or bm.label < 0:
                out.append(1)
                continue
            x = np.ascontiguousarray(self.atlas[:, bm.joints])
            R, nf = len(x), len(bm.g[5])
            r, J = np.empty((R, bm.m)), np.empty((R, bm.m, len(bm.joints)))
            eval_kernel(np.repeat(self._anchor[None], R, axis=0), x, *pack(bm.g), r, J,
                        np.empty((R, len(bm.joints) + nf, 3)))
            sign = np.sign(np.linalg.det(J[:, bm.rows][:, :, bm.cols]))
            for j in bm.middles:
                sign = sign * np.sign(np.cos(x[:, j]))
            s = sign * np.array(self.labels, dtype=float).reshape(R, -1)[:, bm.label]
            if not (np.all(s == 1.0) or np.all(s == -1.0)):
                return None
            out.append(int(s[0]))
        return out

    def _tables(self, models: tuple[BlockModel, ...]) -> dict[str, Any] | None:
        """`_block_tables` of these block models, or None where a block's cuts leave a root's slot
        undecided."""
        signs = self._cut_signs(models)
        if signs is None:
            return None
        K, B = len(models), len(self.labels)
        labels = np.array(self.labels, dtype=np.int64).reshape(B, -1)
        cmax = max(len(bm.ends) for bm in models)
        keys: list[list[tuple[int, ...]]] = []
        bslot = np.zeros((B, K), dtype=np.int64)
        locks = [self.lock_columns[bm.label] if bm.label >= 0 else () for bm in models]
        for k, bm in enumerate(models):
            own = (bm.label, *locks[k]) if bm.label >= 0 else ()
            key = [tuple(int(v) for v in labels[b, list(bm.depends) + list(own)]) for b in range(B)]
            uniq = sorted(set(key), reverse=True)
            keys.append(uniq)
            bslot[:, k] = [uniq.index(c) for c in key]
        S = max(len(u) for u in keys)
        nslot = np.array([len(u) for u in keys], dtype=np.int64)
        rep = np.zeros((K, S), dtype=np.int64)  # a branch that uses each slot
        for k in range(K):
            for s in range(nslot[k]):
                rep[k, s] = int(np.flatnonzero(bslot[:, k] == s)[0])
        # a root's slot: its own sign (-1, 0, 1) and its locked joints' half-turn bits (code, bit q
        # set where locked joint q of the block's unknowns is half a turn from its reference
        # angle); a cut's triple's locked joints are not in the code: the slot of the matching key
        # where one matches (`_close_triples` checks their bits)
        L = len(self.label_blocks)
        mine = [[q for q, c in enumerate(locks[k]) if self.locked_joints[c - L] in bm.ends[: len(bm.cols)]]
                for k, bm in enumerate(models)]
        lmax = max([len(c) for c in mine] + [0])
        land = np.full((K, S, 3, 2 ** lmax), -1, dtype=np.int64)
        lock_idx = np.zeros((K, max(lmax, 1)), dtype=np.int64)
        lock_ref = np.zeros((K, max(lmax, 1)))
        triple_locks: list[list[tuple[int, float, np.ndarray]]] = []
        for k, bm in enumerate(models):
            nl, nk = len(locks[k]), len(mine[k])
            lock_idx[k, :nk] = bm.locks
            lock_ref[k, :nk] = self._reference[[self.locked_joints[locks[k][q] - L] for q in mine[k]]]
            triple_locks.append([])
            for q, c in enumerate(locks[k]):
                j = self.locked_joints[c - L]
                if q not in mine[k]:
                    want = np.array([key[len(key) - nl + q] for key in keys[k]] + [0] * (S - nslot[k]))
                    triple_locks[k].append((bm.ends.index(j), float(self._reference[j]), want))
            for s, slot_key in enumerate(keys[k]):
                if bm.label < 0:
                    land[k, s] = s
                    continue
                head = slot_key[: len(slot_key) - 1 - nl]
                for sign in (-1, 0, 1):
                    for code in range(2 ** nk):
                        bits = {p: -1 if code >> q & 1 else 1 for q, p in enumerate(mine[k])}
                        match = [i for i, key in enumerate(keys[k]) if key[: len(head)] == head
                                 and key[len(head)] == signs[k] * sign
                                 and all(key[len(head) + 1 + p] == v for p, v in bits.items())]
                        if len(match) > 1:
                            return None
                        land[k, s, sign + 1, code] = match[0] if match else -1
        # each slot's assembly: its locked joints' half-turn bits (-1: a block without locked joints)
        slot_lock = np.full((K, S), -1, dtype=np.int64)
        for k, bm in enumerate(models):
            nl = len(locks[k])
            for s, slot_key in enumerate(keys[k]):
                if bm.label >= 0 and nl:
                    slot_lock[k, s] = sum(1 << q for q in range(nl) if slot_key[len(slot_key) - nl + q] < 0)
        hmax = max([len(bm.held) for bm in models] + [1])
        held = np.zeros((K, hmax), dtype=np.int64)
        held_owner = np.zeros((K, hmax), dtype=np.int64)
        held_pos = np.zeros((K, hmax), dtype=np.int64)
        held_slot = np.zeros((K, S, hmax), dtype=np.int64)
        for k, bm in enumerate(models):
            for h, (o, pos) in enumerate(bm.owner):
                held[k, h], held_owner[k, h], held_pos[k, h] = bm.held[h], o, pos
                held_slot[k, : nslot[k], h] = bslot[rep[k, : nslot[k]], o]
        flippable = self.flippable_groups
        fmax = max([len(bm.cols) for bm in models] + [1])
        flips = np.full((K, fmax, 3), -1, dtype=np.int64)
        nflip = np.zeros(K, dtype=np.int64)
        mmax = max([len(bm.middles) for bm in models] + [1])
        middles = np.zeros((K, mmax), dtype=np.int64)
        cols = np.zeros((K, cmax), dtype=np.int64)
        rows_det = np.zeros((K, cmax), dtype=np.int64)
        ref = np.zeros((K, cmax))
        act = np.zeros((K, cmax), dtype=np.bool_)
        atlas = np.zeros((K, S, cmax))
        lo = np.zeros((K, cmax))
        hi = np.zeros((K, cmax))
        alpha = np.zeros((K, cmax))
        span = np.where(self.limited, self.robot.upper - self.robot.lower, 0.0)
        r_lo = np.where(self.limited, self.robot.lower - 0.5 * span, self._centre - math.pi)
        r_hi = np.where(self.limited, self.robot.upper + 0.5 * span, self._centre + math.pi)
        for k, bm in enumerate(models):
            nc = len(bm.cols)
            full = np.array(bm.ends[:nc], dtype=np.int64)
            where = {int(j): i for i, j in enumerate(bm.joints)}
            q = 0
            for grp in flippable:
                if all(j in full for j in grp):
                    flips[k, q, : len(grp)] = [where[j] for j in grp]
                    q += 1
            nflip[k] = q
            middles[k, : len(bm.middles)] = bm.middles
            cols[k, :nc] = bm.cols
            if bm.label >= 0:
                rows_det[k, :nc] = bm.rows
            ref[k, :nc] = self._reference[full]
            act[k, :nc] = np.isin(full, self.actuated)
            atlas[k, : nslot[k], :nc] = self.atlas[rep[k, : nslot[k]]][:, full]
            lo[k, :nc], hi[k, :nc] = r_lo[full], r_hi[full]
            # the additive recurrence of the R_d sequence (plastic-number family): well spread in d dims
            phi = 2.0
            for _ in range(64):
                phi = (1.0 + phi) ** (1.0 / (nc + 1))
            alpha[k, :nc] = (1.0 / phi) ** np.arange(1, nc + 1) % 1.0
        T = (np.array([bm.pinned for bm in models], dtype=np.bool_), np.array([len(bm.cols) for bm in models],
             dtype=np.int64), cols, rows_det, np.array([bm.label for bm in models], dtype=np.int64), middles,
             np.array([len(bm.middles) for bm in models], dtype=np.int64), flips, nflip, held,
             np.array([len(bm.held) for bm in models], dtype=np.int64), held_owner, held_pos, held_slot, land, ref, act,
             np.array([any(o == k for m_ in models for o, _ in m_.owner) for k in range(K)], dtype=np.bool_),
             lock_idx, lock_ref, np.array([len(c) for c in mine], dtype=np.int64), slot_lock)
        kernel_models = tuple((*pack(bm.g), bm.m, bm.nzc, bm.nzn, bm.centre, bm.free, bm.weights) for bm in models)
        # solve order: every block after the blocks it holds joints of, the smallest sub-model first
        # among those ready (a target that one limb cannot reach is dropped before the costlier ones)
        order: list[int] = []
        while len(order) < K:
            ready = [k for k in range(K) if k not in order and all(o in order for o, _ in models[k].owner)]
            order.append(min(ready, key=lambda k: (len(models[k].joints), k)))
        full_cols = np.zeros((K, cmax), dtype=np.int64)
        for k, bm in enumerate(models):
            full_cols[k, : len(bm.ends)] = bm.ends
        return {"models": kernel_models, "T": T, "full_cols": full_cols, "order": order, "nslot": nslot, "bslot": bslot, "atlas": atlas,
                "lo": lo, "hi": hi, "alpha": alpha, "S": S, "cmax": cmax, "triple_locks": triple_locks,
                "ends": [bm.ends for bm in models],
                "nend": np.array([len(bm.ends) for bm in models], dtype=np.int64)}

    def _ik_blocks(self, p: np.ndarray, warm: bool, every_block: bool = False) -> BranchSolutions:
        """`ik` block by block (`block_models`, `block_kernel`): each block's roots once per choice
        of the branches it depends on, combined into the atlas branches (`assemble_kernel`).
        Warm starts are per block slot: the slot's end at the nearest cached point, or at the
        nearest point of this batch solved before it (coarse levels first), whichever is nearer."""
        from scipy.spatial import cKDTree

        tb = self._block_tables
        N, B, n = len(p), len(self.labels), self.n
        K, S, cmax = len(self.block_models), tb["S"], tb["cmax"]
        radius = WARM_RADIUS_FACTOR * self.scale
        best = np.full(N, np.inf)  # distance to the nearest start's source (inf: none)
        cached = None
        if warm:
            best, cached = self._nearest_cached(p, (K, S, cmax + 1))
        # continuation inside the batch: every 64th point, then every 8th, then the rest, each
        # level from the nearest point of the levels before; the points are taken level by level
        # (order) so that each level's slots are one contiguous slice of the arrays
        # (a batch whose points mostly have a cached neighbour, such as a root refinement step, in one go)
        strides = (1,) if np.count_nonzero(np.isfinite(best)) >= 0.9 * N else (64, 8, 1)  # N = 0: no mean of nothing
        levels, taken = [], np.zeros(N, dtype=bool)
        for stride in strides:
            level = np.flatnonzero(~taken & (np.arange(N) % stride == 0))
            if len(level) and not (stride > 1 and 8 * stride >= N):
                levels.append(level)
                taken[level] = True
        order = np.concatenate(levels) if levels else np.arange(0)
        q, best = p[order], best[order]
        starts = np.full((N, K, S, cmax + 1), np.nan)
        if cached is not None:
            near = np.isfinite(best)
            starts[near] = cached[order[near]]
        slots = _Slots.empty(N, K, S, cmax)
        a = 0
        for level in levels:
            b = a + len(level)
            if a:
                # the nearest solved point: all its slot ends within the continuation radius (roots
                # and least-squares points alike); farther, its roots only, and only where it is
                # nearer than the reference position (whose roots are the atlas starts)
                d, src = cKDTree(q[:a]).query(q[a:b])
                near = (d <= radius) & (d < best[a:b])
                starts[a:b][near], best[a:b][near] = slots.end[src[near]], d[near]
                far = ~near & ~np.isfinite(best[a:b]) & (d < np.linalg.norm(q[a:b] - self._anchor, axis=1))
                starts[a:b][far] = np.where(slots.found[src[far]][..., None], slots.end[src[far]], np.nan)
            level_slots = _Slots(*(v[a:b] for v in slots))
            self._solve_slots(q[a:b], starts[a:b], level_slots, every_block, best[a:b])
            level_slots.record_outcome()
            a = b
        x = np.empty((N, B, n))
        end_x = np.empty((N, B, n))
        ok = np.empty((N, B), dtype=np.bool_)
        residual = np.empty((N, B))
        margin = np.empty((N, B))
        if N:
            lo, hi, use, unit, pairs, paired, centre = self._slack_args("all")
            assemble_kernel(order, slots.end, slots.found, slots.res, tb["bslot"], tb["full_cols"],
                             tb["nend"], lo, hi, use, unit, pairs, paired, centre, x, end_x, ok, residual, margin)
        if warm:
            self._remember(q, slots.end)
        return BranchSolutions(x, ok, residual, margin, int(slots.counts[:, 0].sum()), int(slots.counts[:, 1].sum()),
                               end_x)

    def _solve_slots(self, p: np.ndarray, starts: np.ndarray, out: _Slots, every_block: bool = False,
                     source: np.ndarray | None = None) -> None:
        """Every block slot at targets p from warm starts (N, K, S, cmax + 1) (NaN: none; the last
        entry: the outcome of the slot at the start's source point, `_Slots.record_outcome`), written to
        `out` (rows of the caller's arrays); a slot no live branch needs is skipped unless
        every_block. source: (N,) distance [m] from each target to its warm starts' source point
        (inf: none; the default), which decides where a fold's verdict replaces restarts."""
        tb = self._block_tables
        N, B = len(p), len(self.labels)
        alive = np.ones((N, B), dtype=np.bool_)
        starts = np.ascontiguousarray(starts)
        source = np.full(N, np.inf) if source is None else np.ascontiguousarray(source, dtype=float)
        for k in tb["order"] if N else ():
            if every_block:
                alive[:] = True
            before = alive.copy()
            self._run_block(tb, k, p, starts, source, alive, out)
            if self.block_models[k].cuts:
                self._close_triples(k, out, alive)
                self._retry_whole(k, p, starts, source, before, alive, out)

    def _run_block(self, tb: dict[str, Any], k: int, p: np.ndarray, starts: np.ndarray, source: np.ndarray,
                   alive: np.ndarray, out: _Slots) -> None:
        """`block_kernel` on block k of tables tb (`_block_tables`, or its "whole" tables)."""
        gi, gf, m, nzc, nzn, centre, free, weights = tb["models"][k]
        jit.call(block_kernel, k, p, gi, gf, m, nzc, nzn, centre, free, weights, tb["T"], tb["nslot"], tb["bslot"],
                 tb["atlas"], starts, source, tb["lo"], tb["hi"], tb["alpha"], int(self.restarts),
                 WARM_RADIUS_FACTOR * self.scale, alive, out.found, out.dist, out.res, out.end, out.counts)

    def _retry_whole(self, k: int, p: np.ndarray, starts: np.ndarray, source: np.ndarray, before: np.ndarray,
                     alive: np.ndarray, out: _Slots) -> None:
        """Block k (with cuts) once more without them, at the targets where a slot a live branch
        needs had no warm start (a cold start: the atlas configuration only), was not found, its
        best start stalled within the continuation radius of closure, and no slot of its assembly
        was found: from the atlas start the reduced equations can stall where the whole block's
        close (Gepetto's iso6d: 2 of 10,700 inside grid points missed without this, one cold start
        and its neighbour; 0 with it or whole). Warm starts are not retried: on iso6d's workspace
        (rtol 1e-3) that retried half the targets, for one slot found in 222,000 targets. The
        whole block's kernel runs as it would without cuts (`before`: the live branches before
        block k), keeping the slots found."""
        tb = self._block_tables
        whole = tb["whole"]
        S = int(tb["nslot"][k])
        bslot = tb["bslot"][:, k]
        need = np.zeros((len(p), S), dtype=bool)
        for s in range(S):
            need[:, s] = before[:, bslot == s].any(axis=1)
        found = out.found[:, k, :S]
        lock = tb["T"][21][k, :S]
        same = lock[:, None] == lock[None, :]
        assembly = (found.astype(np.int64) @ same.astype(np.int64)) > 0
        cold = ~np.isfinite(starts[:, k, :S, 0])
        miss = need & ~found & cold & (out.res[:, k, :S] < WARM_RADIUS_FACTOR * self.scale) & ~assembly
        rows = np.flatnonzero(miss.any(axis=1))
        if not len(rows):
            return
        # each block's values in `end` and the starts: its unknowns then the triples (cut), its
        # columns (whole); the last entry (the outcome) stays
        width = out.end.shape[-1]
        perm = [np.array([cut.index(j) for j in full] + list(range(len(full), width)))
                for cut, full in zip(tb["ends"], whole["ends"], strict=True)]

        def relaid(a: np.ndarray, back: bool) -> np.ndarray:
            a = a.copy()
            for q, pq in enumerate(perm):
                a[:, q] = a[:, q][..., np.argsort(pq) if back else pq]
            return a

        sub = _Slots(out.found[rows], out.dist[rows], out.res[rows], relaid(out.end[rows], False), out.counts[rows])
        go = before[rows]
        self._run_block(whole, k, p[rows], relaid(starts[rows], False), source[rows], go, sub)
        out.found[rows], out.dist[rows], out.res[rows], out.counts[rows] = sub.found, sub.dist, sub.res, sub.counts
        out.end[rows] = relaid(sub.end, True)
        alive[rows] = go

    def _close_triples(self, k: int, out: _Slots, alive: np.ndarray) -> None:
        """Block k's cut triples (`BlockModel.cuts`) in closed form (`spheres.sphere_angles`) at every
        slot end the kernel left (roots and least-squares points), written after its unknowns in
        `out.end`; a root whose triple's locked joints are not its slot's (no atlas label: the
        kernel's unlabelled roots) is dropped and counted unlabelled, its branches dead."""
        tb = self._block_tables
        bm = self.block_models[k]
        nc, S = len(bm.cols), int(tb["nslot"][k])
        end = out.end[:, k, :S]
        rows, slot = np.nonzero(np.all(np.isfinite(end[..., :nc]), axis=-1))
        if not len(rows):
            return
        x = np.zeros((len(rows), self.n))
        x[:, bm.ends[:nc]] = end[rows, slot, :nc]
        T = tb["T"]
        for h, i in enumerate(bm.held):
            o, pos = int(T[11][k, h]), int(T[12][k, h])
            x[:, bm.joints[i]] = out.end[rows, o, T[13][k, slot, h], pos]
        q = nc
        for cut in bm.cuts:
            js = list(cut.joints)
            x[:, js] = wrap(sphere_angles(self._g, cut, x), self._centre[js])
            end[rows, slot, q: q + 3] = x[:, js]
            q += 3
        wrong = np.zeros(len(rows), dtype=bool)
        for e, ref, want in tb["triple_locks"][k]:
            bit = np.where(np.cos(end[rows, slot, e] - ref) < 0.0, -1, 1)
            wrong |= out.found[rows, k, slot] & (bit != want[slot])
        if wrong.any():
            out.found[rows[wrong], k, slot[wrong]] = False
            out.res[rows[wrong], k, slot[wrong]] = TOL
            np.add.at(out.counts[:, 0], rows[wrong], 1)
            alive &= out.found[:, k, :][:, tb["bslot"][:, k]]
