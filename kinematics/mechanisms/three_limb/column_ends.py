"""The bookkeeping an exact column shares between the three-limb families' kernels (the 3-[P2(US)]'s
and the Delta's `exact` modules): once the candidate ends along a column are sorted and every
working mode's margin is known at the midpoint of each gap between them, the targets' inside
lengths, their interval ends (with the bracket errors), the union's extent and the column's
signature (an FNV-1a hash of which constraint makes which target's ends: neighbouring columns with
the same signature have the same topology) follow the same way for both."""

from __future__ import annotations

import numpy as np
from numba import njit

SIGNATURE_SEED = np.uint64(1469598103934665603)
"""FNV-1a offset basis: the signature of a column before any end (an empty column's)."""

_PRIME = np.uint64(1099511628211)

PARALLEL_COLUMNS = 512
"""Fewer columns per call run on one core: a parallel launch costs more than they do (milliseconds
on a loaded machine; the collision-free exact columns separate a column's intervals by calls on
the few columns that have several)."""


@njit(cache=True)
def other_axes(ax):  # pragma: no cover - compiled
    """The two coordinates (in order) that fix a column along axis ax (0, 1 or 2)."""
    return (1, 2) if ax == 0 else ((0, 2) if ax == 1 else (0, 1))


@njit(cache=True)
def add_gap(c, pm, modes, za, zb, end_id, end_err, prev_in, out_len, out_err, out_ends, zbox,
            h):  # pragma: no cover - compiled
    """The gap (za, zb) [m] of column c, whose working modes' margins at its midpoint are pm (8,):
    adds zb - za to every target inside (modes[t] for t < T - 1, their union last); where a
    target's membership changes, an interval end at za made by the constraint end_id with bracket
    error end_err [m] (into out_ends, out_err and the signature h); widens the union's extent zbox.
    prev_in (T,) carries each target's membership from the previous gap. Returns the new h."""
    T = modes.shape[0] + 1
    best = -np.inf
    for t in range(T):
        if t < T - 1:
            mt = pm[modes[t]]
            best = max(best, mt)
        else:
            mt = best
        inside = mt >= 0.0
        if inside:
            out_len[c, t] += zb - za
        if inside != prev_in[t]:
            out_ends[c, t] += 1
            out_err[c, t] += end_err
            h = (h ^ np.uint64((t + 1) * 64 + end_id + 3)) * _PRIME
            prev_in[t] = inside
        if inside and t == T - 1:
            zbox[c, 0] = min(zbox[c, 0], za)
            zbox[c, 1] = max(zbox[c, 1], zb)
    return h


@njit(cache=True)
def close_column(c, prev_in, end_id, end_err, out_err, out_ends, h):  # pragma: no cover - compiled
    """The column's last end (constraint end_id, error end_err [m]) for every target still inside;
    returns the signature as int64."""
    for t in range(prev_in.shape[0]):
        if prev_in[t]:
            out_ends[c, t] += 1
            out_err[c, t] += end_err
            h = (h ^ np.uint64((t + 1) * 64 + end_id + 3)) * _PRIME
    return np.int64(h >> np.uint64(1))


__all__ = ["PARALLEL_COLUMNS", "SIGNATURE_SEED", "add_gap", "close_column", "other_axes"]
