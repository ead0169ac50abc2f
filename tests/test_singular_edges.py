"""The singularity scan's compiled edge pass against a direct loop over every grid edge."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.analyses.singular_edges import edge_crossings


def _reference(disc, det, margin, modes, K, nx, ny, z_only=False):
    """Every edge of the block, every field, by the definitions of the module docstring."""
    found = []
    steps = [(2, nx * ny)] if z_only else [(0, ny), (1, 1), (2, nx * ny)]
    for d, step in steps:
        for k in range(K - 1 if d == 2 else K):
            for i in range(nx - 1 if d == 0 else nx):
                for j in range(ny - 1 if d == 1 else ny):
                    a = (k * nx + i) * ny + j
                    b = a + step
                    for limb in range(disc.shape[1]):
                        fa, fb = disc[a, limb], disc[b, limb]
                        if (fa >= 0) != (fb >= 0) and math.isfinite(fa) and math.isfinite(fb):
                            end = a if fa >= 0 else b
                            found.append((1, limb, a, b, bool((margin[end, modes] >= 0).any()), fa / (fa - fb)))
                    reach = (disc[a] >= 0).all() and (disc[b] >= 0).all()
                    for m in modes:
                        fa, fb = det[a, m], det[b, m]
                        if (fa > 0) != (fb > 0) and reach and math.isfinite(fa) and math.isfinite(fb):
                            t = fa / (fa - fb) if math.isfinite(fa / (fa - fb)) else 0.5
                            found.append((2, m, a, b, bool(margin[a, m] >= 0 and margin[b, m] >= 0), t))
    return found


@pytest.mark.parametrize(("K", "nx", "ny", "L", "M", "z_only"),
                         [(3, 4, 5, 3, 8, False), (1, 6, 3, 2, 4, False), (2, 3, 4, 3, 70, False),
                          (2, 4, 4, 3, 8, True)])
def test_edge_pass_matches_every_edge(K, nx, ny, L, M, z_only):
    rng = np.random.default_rng(7 + K * nx * ny + M)
    N = K * nx * ny
    # small integers: many exact zeros (the >= / > sides), a few NaNs (no evidence of a crossing)
    disc = rng.integers(-1, 4, (N, L)).astype(float)  # mostly reaching: type II occurs
    det = rng.integers(-2, 3, (N, M)).astype(float)
    margin = rng.normal(size=(N, M))
    disc[rng.random((N, L)) < 0.05] = np.nan
    det[rng.random((N, M)) < 0.05] = np.nan
    modes = rng.permutation(M)[: max(1, M // 2)].tolist()
    kind, which, t, a, b, inner = edge_crossings(disc, det, margin, modes, K, nx, ny, z_only=z_only)
    ref = _reference(disc, det, margin, modes, K, nx, ny, z_only)
    got = list(zip(kind.tolist(), which.tolist(), a.tolist(), b.tolist(), inner.tolist(), t.tolist(), strict=True))
    assert len(ref) > 10  # the fields do cross
    # the same crossings (t exactly: both compute fa / (fa - fb)); the order is the module's
    assert sorted(got) == sorted(ref)
    # the documented order: by direction, then type I limb by limb, then the modes as given, then the edge
    direction = np.where(b - a == nx * ny, 2, np.where(b - a == 1, 1, 0))
    field = [w if k == 1 else L + modes.index(w) for k, w in zip(kind.tolist(), which.tolist(), strict=True)]
    key = list(zip(direction.tolist(), field, a.tolist(), strict=True))
    assert key == sorted(key)
