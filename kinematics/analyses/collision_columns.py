"""Collision-free exact columns: the collision margin along the kinematic intervals of the
closed-form mechanisms' exact columns (3-[P2(US)], Delta).

Along an axis-parallel column each working mode's kinematic inside set is a union of intervals with
algebraic ends (`kinematics.mechanisms.p2us.exact`, `kinematics.mechanisms.delta.exact`); they come
from the mode's own exact columns, one call per batch of columns: where a column has more than one
interval in a z range (more than two ends), the range is halved for those columns until each part
holds one. Inside an interval the configuration is a smooth closed-form function of z, and so is
every pair's signed distance d_p. The collision margin is checked only in the pre-scan's close
cells (`kinematics.analyses.collision_prescan`; elsewhere no pair comes near contact and the whole
interval is free):

* samples every `spacing` [m] (at least three, the ends nudged EDGE inside), then, per gap of
  width w between two samples, whether it can hold a root: a pair clear at both ends stays clear
  when d_p(a) + d_p(b) > s_p w (s_p the pre-scan's observed slope times SAFETY) or when
  min(d_p(a), d_p(b)) > k_p w^2 / 8 (k_p SAFETY times the largest |second difference| / spacing^2
  of the samples at the gap's ends: the sag below its chord); the smallest distance m = min_p d_p,
  negative at both ends, stays negative when some pair provably does or |m(a)| + |m(b)| >
  max_p s_p w; where m changes sign, every pair clear at both ends must provably stay clear (the
  root is sought on one pair, and another may dip into contact and out again inside the gap).
  Gaps that can are halved (keeping their curvature bound), at most MAX_REFINE times;
* every sign change is bracketed to `root_tol` [m] (Illinois false position, bisection from the
  8th step on) on one pair's distance, its two shapes alone placed
  (`AnalyticDistances.pair_distances`): a watched pair's, or, for the smallest distance, the pair
  smallest at the gap's colliding end, whose root is the smallest distance's when every pair is
  clear at the final bracket's free end (one full evaluation; else the smallest distance itself
  is refined over the gap); a gap and pair shared by several functions is refined once. The
  binding pair at a root is that pair;
* the collision-free pieces of every branch, and their unions over the branches, give the
  targets' lengths: each branch's, the kinematic union (the exact columns' own), the union with
  each watched pair alone, the union with every pair.

Errors: the kinematic ends' (the exact columns') plus `root_tol` per collision end. The signature
is the kinematic one combined with, per target (the watched pairs' own only with
`WATCHED_SIGNATURE`), the binding pair of each collision end in order,
so the column engine locates where a collision end appears, vanishes or changes pair as it does a
kinematic one. What it can miss, beside the exact columns' caveats: the slopes are observed on the
pre-scan's grid and the curvatures on the samples, not bounded (a pair closing in faster, as near a
reach boundary where the joints turn fast, can dip below zero between two samples), and a dip
narrower than spacing / 2^MAX_REFINE;
the check run halves the spacing (`for_check`).

Evaluations: the 3-[P2(US)]'s samples and pair roots are compiled single passes from column points
to distances (`kinematics.analyses.collision_fused`, `COMPILED`), the same values to the last bit
as the batched path (configurations, then `AnalyticDistances`, the roots by `illinois`) that the
other families take.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from kinematics.analyses.collision_column_kernels import (
    ambiguous_gaps,
    curvatures,
    smallest,
    split_close,
    union_pieces,
)
from kinematics.analyses.collision_fused import distances, illinois, pair_roots
from kinematics.analyses.collision_prescan import SAFETY, Prescan
from kinematics.analyses.collisions import CollisionMargin, configurations
from kinematics.mechanisms.p2us.configurations import kernel_data

SPACING = 8.0
"""The collision margin's first samples along a column are SPACING x the column step apart (the gap
tests refine where a root may hide; the check run halves it). p2us-results, mode ---, rtol 1e-3,
first run: at 2 x 4.5M samples, 32.8 s CPU; at 4 x 3.2M, 29.0 s, the same volume to 1e-7 m^3 and
every pair's removal within 1e-5 m^3 (errors 6e-5); at 1 x 1.5 x the CPU time of 2 x. With the
check run: at 8 x (MAX_REFINE 11), 26.5 s CPU against 34-36 s at 4 x (10), the volume within
3e-8 m^3, every removal within 6e-6 m^3 (errors 2.9e-5, 3.5e-5); at 16 x, 2.7 x the columns."""

SIGNATURE_PAIRS = True
"""Whether a collision end's binding pair enters the column's signature (else only its rank; off,
the same run took 5 % more columns)."""

PAIR_ROOTS = True
"""Whether roots are refined on one pair's distance (module docstring; else every root on its
function: the smallest distance, or a watched pair's, evaluating every pair)."""

WATCHED_SIGNATURE = False
"""Whether the collision ends of the watched pairs' own targets (the union with one pair alone)
enter the signature too. Off, the quadrature locates the breaks of the branches' and the union's
collision-free lengths only; a watched target's own ends are kinks its adaptive rules refine
around (the same run: 173k columns on, 140k off, every removal the same within 1e-6 m^3, errors
5e-5)."""

CHUNK_COLUMNS = 8192
"""Most columns per batch (about 20 samples of every pair per column)."""

EDGE = 1e-10
"""[m] samples at a kinematic end are taken this far inside (the configuration there exists)."""

MAX_REFINE = 11
"""Most halvings of a gap between two samples that the slopes say may hold a root (the narrowest
dip they resolve, SPACING / 2^MAX_REFINE = 4 steps / 1024, as at 4 x and 10 halvings)."""

MAX_SPLITS = 40
"""Most halvings of a z range while separating a column's kinematic intervals."""

ROOT_STEPS = 80
"""Most steps of the root refinement (each halves the bracket from the 8th on)."""

COMPILED = True
"""Whether the 3-[P2(US)]'s samples and pair roots are evaluated by compiled single passes
(`collision_fused`; else batched: configurations, then distances, the roots by `illinois` on
`_pair_values`; the same values)."""

class CollisionColumns:
    """Exact-columns function (`ExactColumnsFn`) of a `CollisionMargin`'s targets, collision
    margin included (module docstring): each branch, the kinematic union, the union with each
    watched pair alone, the union."""

    def __init__(self, margin: CollisionMargin, prescan: Prescan, spacing: float, root_tol: float) -> None:
        self.margin, self.prescan = margin, prescan
        self.spacing, self.root_tol = float(spacing), float(root_tol)
        mech = margin.mech
        self.union = _exact_of(margin.kinematic)
        self.branch = [_exact_of(mech.margin([b], margin.limits)) for b in margin.branches]
        slopes = np.array(prescan.slopes, dtype=float)
        finite = np.where(np.isfinite(slopes), slopes, 0.0)
        worst = finite.max(axis=1, keepdims=True) if slopes.size else np.zeros((len(self.branch), 1))
        self.slopes = SAFETY * np.where(np.isfinite(slopes), slopes, worst)  # (B, P)
        self.evaluations = 0
        self.kernel_data = [kernel_data(mech.params, margin.robot.model, name) if COMPILED and mech.family == "p2us"
                            else None for name in margin.branches]
        """Per branch, `p2us.configurations.kernel_data` for the compiled root refinement (None: batched)."""

    def halved(self) -> CollisionColumns:
        """The same with half the sampling spacing (the check run's)."""
        return CollisionColumns(self.margin, self.prescan, 0.5 * self.spacing, self.root_tol)

    def __call__(self, base: np.ndarray, axis: int, z0: float, z1: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        base = np.ascontiguousarray(base, dtype=float)
        if len(base) > CHUNK_COLUMNS:  # bounded memory: the samples' distances are (N, P)
            parts = [self._batch(base[k:k + CHUNK_COLUMNS], axis, z0, z1) for k in range(0, len(base), CHUNK_COLUMNS)]
            length, err, ends, sig, zbox = (np.concatenate(x) for x in zip(*parts, strict=True))
            return length, err, ends, sig, zbox
        return self._batch(base, axis, z0, z1)

    def _batch(self, base: np.ndarray, axis: int, z0: float, z1: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        M, B, W = len(base), len(self.branch), len(self.margin.watched)
        T = B + W + 2
        kin = self.union(base, axis, z0, z1)
        klen, kerr, _kends, ksig, _ = kin
        length, err = np.zeros((M, T)), np.zeros((M, T))
        ends = np.zeros((M, T), np.int64)
        sig = ksig.astype(np.uint64)
        zbox = np.empty((M, 2))
        zbox[:, 0], zbox[:, 1] = np.inf, -np.inf
        length[:, B], err[:, B] = klen[:, B], kerr[:, B]
        # one branch: its own columns are the union's (targets: the branch, the union)
        pieces = [self._branch_pieces(b, base, axis, z0, z1, kin if B == 1 else None) for b in range(B)]
        col = np.concatenate([p[0] for p in pieces])
        a, e, ca, ce = (np.ascontiguousarray(np.concatenate([p[n] for p in pieces], axis=1)) for n in range(1, 5))
        first = np.cumsum([0] + [len(p[0]) for p in pieces])
        # a branch's pieces lie in disjoint segments of its columns, in the same order for every
        # function: one sort by the first function's starts serves them all
        own = [first[b] + np.lexsort((p[1][0], p[0])) for b, p in enumerate(pieces)]
        for t in [*range(B), *range(B + 1, T)]:
            f = 0 if t < B or t == T - 1 else t - B
            # the union over several branches: their pieces overlap, sorted by this function's starts
            order = own[t] if t < B else (own[0] if B == 1 else np.lexsort((a[f], col)))
            union_pieces(col, order, a, e, ca, ce, f, t, t == T - 1, self.root_tol, SIGNATURE_PAIRS,
                         WATCHED_SIGNATURE or not B < t < T - 1, length, err, ends, sig, zbox)
            err[:, t] += pieces[t][5] if t < B else sum(p[5] for p in pieces)
        out_sig = (sig >> np.uint64(1)).astype(np.int64)
        zbox[~np.isfinite(zbox)] = np.nan
        return length, err, ends, out_sig, zbox

    # -- one branch ----------------------------------------------------------------------------
    def _branch_pieces(self, b: int, base: np.ndarray, ax: int, z0: float, z1: float,
                       first: tuple[np.ndarray, ...] | None = None) -> tuple[Any, ...]:
        """Branch b's collision-free pieces per function (0: every pair, 1 + w: watched pair w
        alone): col (K,), starts (F, K), ends (F, K), start codes and end codes (F, K) (binding
        pair + 1 at a collision end, else 0), and the kinematic ends' errors (M,)."""
        M = len(base)
        F = 1 + len(self.margin.watched)
        col, a, e, kerr = self._intervals(b, base, ax, z0, z1, first)
        lo, g = self.prescan.lo[ax], self.prescan.spacing[ax]
        cells = self.prescan.close_rows(b, base, ax)
        sc, su, sv, checked = split_close(col, a, e, cells, lo, g)
        free_col, free_a, free_e = sc[~checked], su[~checked], sv[~checked]
        n_free = len(free_col)
        pc, pa, pe, pca, pce = self._checked_pieces(b, base, ax, sc[checked], su[checked], sv[checked])
        colf = np.concatenate([free_col, pc])
        starts = np.concatenate([np.repeat(free_a[None], F, 0), pa], axis=1)
        stops = np.concatenate([np.repeat(free_e[None], F, 0), pe], axis=1)
        zero = np.zeros((F, n_free), np.int64)
        return (colf, starts, stops, np.concatenate([zero, pca], axis=1), np.concatenate([zero, pce], axis=1),
                np.bincount(col, weights=kerr, minlength=M))

    def _intervals(self, b: int, base: np.ndarray, ax: int, z0: float, z1: float,
                   first: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Branch b's kinematic intervals: column (K,), start, end [m], the ends' error [m]
        (`first`: its exact columns' outputs over [z0, z1] when already known)."""
        out: list[tuple[np.ndarray, ...]] = []
        todo = [(np.arange(len(base)), z0, z1, 0)]
        while todo:
            idx, lo, hi, depth = todo.pop()
            ln, er, en, _, zb = first if first is not None else self.branch[b](base[idx], ax, lo, hi)
            first = None
            one = (en[:, 0] == 2) | ((en[:, 0] > 2) & (depth >= MAX_SPLITS))
            # past MAX_SPLITS (two intervals touching): the extent, its excess charged as error
            out.append((idx[one], zb[one, 0], zb[one, 1], er[one, 0] + (zb[one, 1] - zb[one, 0] - ln[one, 0])))
            many = (en[:, 0] > 2) & (depth < MAX_SPLITS)
            if many.any():
                mid = 0.5 * (lo + hi)
                todo += [(idx[many], lo, mid, depth + 1), (idx[many], mid, hi, depth + 1)]
        col, a, e, err = (np.concatenate(x) for x in zip(*out, strict=True))
        return col.astype(np.int64), a, e, np.abs(err)

    def _configurations(self, b: int, base: np.ndarray, ax: int, col: np.ndarray, z: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
        """(N, nq) configurations of branch b at the points of columns `col` at `z`, and where
        they exist (rounding at a reach end can leave none: the kinematic end decides there)."""
        others = [k for k in range(3) if k != ax]
        pts = np.empty((len(z), 3))
        pts[:, others[0]], pts[:, others[1]], pts[:, ax] = base[col, 0], base[col, 1], z
        self.evaluations += len(z)
        m = self.margin
        q = configurations(m.mech, m.robot, pts, m.branches[b])
        return q, np.isfinite(q).all(axis=1)

    def _evaluate(self, b: int, base: np.ndarray, ax: int, col: np.ndarray, z: np.ndarray) -> np.ndarray:
        """(N, P) pair distances [m] (signs exact, `AnalyticDistances.distances(signs=True)`) at
        the points of columns `col` at `z` in branch b (+inf where no configuration exists)."""
        kd = self.kernel_data[b]
        if kd is not None:  # compiled (`collision_fused.distances`): the same values
            d, need = distances(kd, self.margin.distances, base[col], ax, z)
            self.evaluations += len(z)
            if need.any():
                d[need] = self._evaluate_batched(b, base, ax, col[need], z[need])
            return d
        return self._evaluate_batched(b, base, ax, col, z)

    def _evaluate_batched(self, b: int, base: np.ndarray, ax: int, col: np.ndarray, z: np.ndarray) -> np.ndarray:
        """`_evaluate` by its batches: the configurations, then the distances."""
        q, good = self._configurations(b, base, ax, col, z)
        if good.all():
            return self.margin.distances.distances(q, signs=True)
        d = np.full((len(z), len(self.margin.distances.kinds)), np.inf)
        if good.any():
            d[good] = self.margin.distances.distances(q[good], signs=True)
        return d

    def _pair_values(self, b: int, base: np.ndarray, ax: int, col: np.ndarray, z: np.ndarray, pair: np.ndarray
                     ) -> np.ndarray:
        """(N,) the distance [m] of pair pair[n] alone (sign exact) at the point of column col[n]
        at z[n] in branch b (+inf where no configuration exists)."""
        q, good = self._configurations(b, base, ax, col, z)
        out = np.full(len(z), np.inf)
        if good.any():
            out[good] = self.margin.distances.pair_distances(q[good], pair[good], signs=True)
        return out

    def _functions(self, d: np.ndarray) -> np.ndarray:
        """(N, F): the smallest distance over the pairs, then each watched pair's."""
        return smallest(d, np.asarray(self.margin.watched, dtype=np.int64))[0]

    def _checked_pieces(self, b: int, base: np.ndarray, ax: int, col: np.ndarray, u: np.ndarray, v: np.ndarray
                        ) -> tuple[np.ndarray, ...]:
        """Collision-free pieces of the sub-intervals [u, v] of columns `col` where pairs can
        come near contact: col (G,), starts, ends, start codes, end codes (F, G), one per final gap."""
        F = 1 + len(self.margin.watched)
        if not len(col):
            empty = np.zeros((F, 0))
            return np.zeros(0, np.int64), empty, empty, empty.astype(np.int64), empty.astype(np.int64)
        n = np.maximum(2, np.ceil((v - u) / self.spacing - 1e-9).astype(np.int64))
        seg = np.repeat(np.arange(len(col)), n + 1)
        k = np.arange(len(seg)) - np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)
        z = u[seg] + (v - u)[seg] * (k / n[seg])
        z[np.cumsum(n + 1) - 1] = v
        nudge = np.minimum(EDGE, (v - u) / 4)[seg]
        d = self._evaluate(b, base, ax, col[seg], np.clip(z, u[seg] + nudge, v[seg] - nudge))
        curv = curvatures(d, k, n[seg], ((v - u) / n)[seg])
        left = np.flatnonzero(k < n[seg])
        gc, za, zb, ia, ib = col[seg[left]], z[left], z[left + 1], left, left + 1
        s = self.slopes[b]
        s_min = float(s.max(initial=0.0))
        watched = np.ascontiguousarray(self.margin.watched, dtype=np.int64)
        done: list[tuple[np.ndarray, ...]] = []
        for level in range(MAX_REFINE + 1):
            amb = np.zeros(len(gc), np.bool_)
            if level < MAX_REFINE:
                ambiguous_gaps(d, curv, ia, ib, SAFETY, zb - za, s, s_min, watched, amb)
            fn, arg = smallest(d, watched)
            keep = ~amb
            ka, kb = ia[keep], ib[keep]
            # each end's smallest pair, and its distance at the other end (a root of the smallest
            # distance is first sought as that pair's own)
            done.append((gc[keep], za[keep], zb[keep], fn[ka], fn[kb], arg[ka], arg[kb], d[ka, arg[kb]], d[kb, arg[ka]]))
            if not amb.any():
                break
            # each gap to halve gets its own three samples (a, b, midpoint), its parent's curvature bound
            m = int(amb.sum())
            gc, za, zb = gc[amb], za[amb], zb[amb]
            zm = 0.5 * (za + zb)
            kk = SAFETY * np.maximum(curv[ia[amb]], curv[ib[amb]])
            d = np.concatenate([d[ia[amb]], d[ib[amb]], self._evaluate(b, base, ax, gc, zm)])
            curv = np.concatenate([kk, kk, kk]) / SAFETY
            r = np.arange(m)
            gc, za, zb = np.concatenate([gc, gc]), np.concatenate([za, zm]), np.concatenate([zm, zb])
            ia, ib = np.concatenate([r, r + 2 * m]), np.concatenate([r + 2 * m, r + m])
        gc, za, zb, fa, fb, pa, pb, xa, xb = (np.concatenate(x) for x in zip(*done, strict=True))
        return self._pieces(b, base, ax, gc, za, zb, fa, fb, pa, pb, xa, xb)

    def _pieces(self, b: int, base: np.ndarray, ax: int, gc: np.ndarray, za: np.ndarray, zb: np.ndarray,
                fa: np.ndarray, fb: np.ndarray, pa: np.ndarray, pb: np.ndarray, xa: np.ndarray, xb: np.ndarray
                ) -> tuple[np.ndarray, ...]:
        """Each final gap's free piece per function (values fa, fb (G, F) at its ends, smallest
        pairs pa, pb there, pa's distance xb at the upper end and pb's xa at the lower), its sign
        changes refined to roots."""
        F = fa.shape[1]
        starts, stops = np.repeat(za[None], F, 0), np.repeat(zb[None], F, 0)
        ca, ce = np.zeros((F, len(gc)), np.int64), np.zeros((F, len(gc)), np.int64)
        gi, fi = np.nonzero((fa >= 0) != (fb >= 0))
        root, code = self._roots(b, base, ax, gc, za, zb, fa, fb, pa, pb, xa, xb, gi, fi)
        up = fa[gi, fi] < 0  # colliding below the root: the piece starts there
        starts[fi[up], gi[up]], ca[fi[up], gi[up]] = root[up], code[up] + 1
        stops[fi[~up], gi[~up]], ce[fi[~up], gi[~up]] = root[~up], code[~up] + 1
        out = (fa < 0) & (fb < 0)
        stops[out.T] = starts[out.T]  # empty pieces (dropped by the union)
        return gc, starts, stops, ca, ce

    def _roots(self, b: int, base: np.ndarray, ax: int, gc: np.ndarray, za: np.ndarray, zb: np.ndarray,
               fa: np.ndarray, fb: np.ndarray, pa: np.ndarray, pb: np.ndarray, xa: np.ndarray, xb: np.ndarray,
               gi: np.ndarray, fi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The root [m] of function fi[r] in gap gi[r] (its values change sign there) to
        `root_tol`, and the pair that binds there.

        Each is first sought as one pair's own root (`AnalyticDistances.pair_distances`: that
        pair's two shapes alone, about a third of a full evaluation): a watched pair's, or, for
        the smallest distance, the pair smallest at the gap's colliding end; a gap and pair
        shared by several functions is refined once. The smallest distance's root is that
        pair's when every pair is clear at the final bracket's free end (one full evaluation
        there); where one is not (another pair takes over inside the gap), the smallest
        distance itself is refined over the gap."""
        n_pairs = len(self.margin.distances.kinds)
        lower = fa[gi, fi] < 0  # colliding at the gap's lower end
        if not PAIR_ROOTS:
            return self._smallest_roots(b, base, ax, gc[gi], za[gi], zb[gi], fa[gi, fi], fb[gi, fi],
                                        np.where(lower, pa[gi], pb[gi]), fi)
        pair_of = np.concatenate([[0], self.margin.watched]).astype(np.int64)
        pair = np.where(fi > 0, pair_of[fi], np.where(lower, pa[gi], pb[gi]))
        va = np.where(fi > 0, fa[gi, fi], np.where(lower, fa[gi, 0], xa[gi]))
        vb = np.where(fi > 0, fb[gi, fi], np.where(lower, xb[gi], fb[gi, 0]))
        _, first, task = np.unique(gi * n_pairs + pair, return_index=True, return_inverse=True)
        g, k = gi[first], pair[first]
        lo, hi, ylo = self._pair_roots(b, base, ax, gc[g], za[g], zb[g], va[first], vb[first], k)
        root, code = 0.5 * (lo + hi), k.copy()
        root, code = root[task], code[task]
        smallest = np.flatnonzero(fi == 0)
        if len(smallest):  # every pair clear at the free end: the smallest distance's root too
            t = task[smallest]
            free = np.where(ylo[t] >= 0, lo[t], hi[t])
            clear = self._evaluate(b, base, ax, gc[gi[smallest]], free).min(axis=1, initial=np.inf) >= 0
            again = smallest[~clear]
            if len(again):
                root[again], code[again] = self._smallest_roots(b, base, ax, gc[gi[again]], za[gi[again]],
                                                                zb[gi[again]], fa[gi[again], 0], fb[gi[again], 0],
                                                                pair[again])
        return root, code

    def _pair_roots(self, b: int, base: np.ndarray, ax: int, col: np.ndarray, za: np.ndarray, zb: np.ndarray,
                    fa: np.ndarray, fb: np.ndarray, pair: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Brackets (za, zb) (values fa, fb of opposite signs) of pair pair[r]'s own root along
        column col[r] narrowed to `root_tol`: the final brackets and their lower ends' values, by
        `collision_fused.pair_roots` (compiled, the 3-[P2(US)]'s) where it can, else `illinois`
        on `_pair_values` (the same steps)."""
        lo, hi, ylo = za.copy(), zb.copy(), fa.copy()
        todo = np.arange(len(za))
        kd = self.kernel_data[b]
        if kd is not None:
            lo, hi, ylo, n, failed = pair_roots(kd, self.margin.distances, base[col], ax, za, zb, fa, fb, pair,
                                                self.root_tol, ROOT_STEPS)
            self.evaluations += int(n.sum())
            todo = np.flatnonzero(failed)
        if len(todo):
            def one_pair(rows: np.ndarray, x: np.ndarray) -> np.ndarray:
                return self._pair_values(b, base, ax, col[todo[rows]], x, pair[todo[rows]])

            lo[todo], hi[todo], ylo[todo], _ = illinois(one_pair, za[todo], zb[todo], fa[todo], fb[todo],
                                                        self.root_tol, ROOT_STEPS)
        return lo, hi, ylo

    def _smallest_roots(self, b: int, base: np.ndarray, ax: int, col: np.ndarray, za: np.ndarray, zb: np.ndarray,
                        fa: np.ndarray, fb: np.ndarray, pair: np.ndarray, fi: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Roots [m] of function fi (default 0: the smallest distance; `_functions`), every pair
        evaluated, in brackets (za, zb) (values fa, fb of opposite signs) to `root_tol`, and the
        pair that binds: a watched function's own, else the smallest pair at each bracket's
        colliding end (`pair`: at the gap's)."""
        fi = np.zeros(len(za), np.int64) if fi is None else fi
        pair = np.where(fi > 0, np.concatenate([[0], self.margin.watched]).astype(np.int64)[fi], pair)

        def value(rows: np.ndarray, x: np.ndarray) -> np.ndarray:
            d = self._evaluate(b, base, ax, col[rows], x)
            y = self._functions(d)[np.arange(len(rows)), fi[rows]]
            neg = (y < 0) & (fi[rows] == 0)
            pair[rows[neg]] = d[neg].argmin(axis=1)
            return y

        lo, hi, _, _ = illinois(value, za, zb, fa, fb, self.root_tol, ROOT_STEPS)
        return 0.5 * (lo + hi), pair


class ExactCollisionMargin(CollisionMargin):
    """A `CollisionMargin` with exact columns (`CollisionColumns`), for the column engine; the
    check run (`for_check`) samples the collision margin at half the spacing."""

    def __init__(self, margin: CollisionMargin, prescan: Prescan, spacing: float, root_tol: float,
                 columns: CollisionColumns | None = None) -> None:
        super().__init__(margin.mech, margin.robot, margin.distances, margin.branches, margin.limits,
                         [int(w) for w in margin.watched], prescan)
        self.exact_columns = columns or CollisionColumns(self, prescan, spacing, root_tol)

    def for_check(self) -> ExactCollisionMargin:
        cols = self.exact_columns.halved()
        return ExactCollisionMargin(self, cols.prescan, cols.spacing, cols.root_tol, cols)


def _exact_of(margin: Any) -> Any:
    """A kinematic margin's exact columns (`ExactColumnsFn`)."""
    return margin.exact_columns


def has_exact_columns(margin: CollisionMargin) -> bool:
    """Whether the mechanism's kinematic margin has exact columns (3D closed-form families)."""
    return getattr(margin.kinematic, "exact_columns", None) is not None and margin.mech.task_dim == 3


__all__ = ["CHUNK_COLUMNS", "COMPILED", "EDGE", "MAX_REFINE", "MAX_SPLITS", "PAIR_ROOTS", "ROOT_STEPS", "CollisionColumns", "ExactCollisionMargin",
           "has_exact_columns"]
