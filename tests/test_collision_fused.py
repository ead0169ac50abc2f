"""The compiled single-pass evaluations of the collision-free exact columns
(kinematics.analyses.collision_fused) against the batched path they replace: configurations
(`collisions.configurations`), then `AnalyticDistances.distances`/`pair_distances(signs=True)`,
the roots by the batched `illinois`. They do the same operations in the same order, so the values
are compared bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses import collision_fused as cf
from kinematics.analyses.collision_prescan import Prescan
from kinematics.analyses.collision_volume import PRESCAN_CELLS
from kinematics.analyses.collisions import CollisionMargin, collision_model_of, configurations
from kinematics.generic.capsules import PARALLEL_MIN, AnalyticDistances
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.p2us.configurations import kernel_data
from kinematics.model.robot import load_robot


@pytest.fixture(scope="module")
def p2us_results():
    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    return (mech, robot, AnalyticDistances(collision_model_of(robot)), *mech.bounding_box("all"))


def _points(lo, hi, ax, base, z):
    others = [k for k in range(3) if k != ax]
    p = np.empty((len(z), 3))
    p[:, others[0]], p[:, others[1]], p[:, ax] = base[:, 0], base[:, 1], z
    return p


def _batched(mech, robot, dist, pts, mode):
    """`CollisionColumns._evaluate_batched`'s values: +inf where no configuration."""
    q = configurations(mech, robot, pts, mode)
    good = np.isfinite(q).all(axis=1)
    d = np.full((len(pts), len(dist.kinds)), np.inf)
    d[good] = dist.distances(q[good], signs=True)
    return d


@pytest.mark.parametrize("n", [PARALLEL_MIN - 1, 3 * PARALLEL_MIN])  # one thread, every core
def test_distances_are_the_batched_ones(p2us_results, rng, n):
    """At n random points of the box (some out of reach: +inf in both), in two working modes,
    every pair's distance from the compiled pass equals the batched path's, where the compiled
    pass needs no coal (a rod beside a plate: the batched path evaluates those rows)."""
    mech, robot, dist, lo, hi = p2us_results
    ax = 2
    others = [0, 1]
    base = lo[others] + (hi[others] - lo[others]) * rng.random((n, 2))
    z = lo[ax] + (hi[ax] - lo[ax]) * rng.random(n)
    for mode in ("---", "+-+"):
        d, need = cf.distances(kernel_data(mech.params, robot.model, mode), dist, base, ax, z)
        ref = _batched(mech, robot, dist, _points(lo, hi, ax, base, z), mode)
        inside = np.isfinite(ref).all(axis=1)
        assert 0.1 * n < inside.sum() < 0.9 * n  # both kinds of points
        assert need.sum() < 0.3 * n  # rows with a rod beside a plate (coal's)
        assert np.array_equal(d[~need], ref[~need])


def test_pair_roots_are_the_batched_ones(p2us_results, rng):
    """Brackets of sign changes of random pairs' distances along random columns (mode ---): the
    compiled Illinois loop (`pair_roots`) ends on the same brackets, values and evaluation
    counts as the batched `illinois` on `AnalyticDistances.pair_distances(signs=True)`."""
    mech, robot, dist, lo, hi = p2us_results
    ax, mode, tol = 2, "---", 1e-10
    kd = kernel_data(mech.params, robot.model, mode)
    n, K = 3000, 12  # columns, samples per column
    base = lo[:2] + (hi[:2] - lo[:2]) * rng.random((n, 2))
    zs = np.linspace(lo[ax], hi[ax], K)
    col = np.repeat(np.arange(n), K)
    d, need = cf.distances(kd, dist, base[col], ax, np.tile(zs, n))
    d = d.reshape(n, K, -1)
    # per column, each pair's first sign change between neighbouring samples (finite at both)
    a, b = d[:, :-1], d[:, 1:]
    change = np.isfinite(a) & np.isfinite(b) & ((a >= 0) != (b >= 0)) & ~need.reshape(n, K)[:, :-1, None]
    c, s, p = np.nonzero(change)
    assert len(c) > 500
    za, zb, fa, fb = zs[s], zs[s + 1], a[c, s, p], b[c, s, p]
    lo_, hi_, ylo, evals, failed = cf.pair_roots(kd, dist, base[c], ax, za, zb, fa, fb, p, tol, 80)
    count = np.zeros(len(c), np.int64)

    def one_pair(rows, x):
        count[rows] += 1
        q = configurations(mech, robot, _points(lo, hi, ax, base[c[rows]], x), mode)
        good = np.isfinite(q).all(axis=1)
        out = np.full(len(rows), np.inf)
        out[good] = dist.pair_distances(q[good], p[rows][good], signs=True)
        return out

    ref = cf.illinois(one_pair, za, zb, fa, fb, tol, 80)
    ok = ~failed
    assert ok.mean() > 0.95
    assert np.all(hi_[ok] - lo_[ok] <= tol)
    assert np.array_equal(lo_[ok], ref[0][ok]) and np.array_equal(hi_[ok], ref[1][ok])
    assert np.array_equal(ylo[ok], ref[2][ok]) and np.array_equal(evals[ok], count[ok])


def test_columns_are_the_batched_ones(p2us_results, rng, monkeypatch):
    """The collision-free exact columns of p2us-results (mode ---, three watched pairs) on 150
    random columns: every output (lengths, errors, ends, signatures, extents) the same with the
    compiled evaluations (`COMPILED`) as with the batched ones."""
    import kinematics.analyses.collision_columns as cc

    mech, robot, dist, lo, hi = p2us_results
    scan = Prescan(CollisionMargin(mech, robot, dist, ["---"], "all"), lo, hi, PRESCAN_CELLS)
    watched = np.flatnonzero(scan.counts)[:3]
    margin = CollisionMargin(mech, robot, dist, ["---"], "all", watched, prescan=scan)
    ax = int(np.argmin(hi - lo))
    others = [k for k in range(3) if k != ax]
    base = lo[others] + (hi[others] - lo[others]) * rng.random((150, 2))
    fused = cc.ExactCollisionMargin(margin, scan, 0.01, 1e-10)
    assert fused.exact_columns.kernel_data[0] is not None
    one = fused.exact_columns(base, ax, lo[ax], hi[ax])
    monkeypatch.setattr(cc, "COMPILED", False)
    batched = cc.ExactCollisionMargin(margin, scan, 0.01, 1e-10)
    assert batched.exact_columns.kernel_data[0] is None
    two = batched.exact_columns(base, ax, lo[ax], hi[ax])
    assert (one[0][:, 1] - one[0][:, -1]).max() > 0.05  # collisions shorten columns
    for x, y in zip(one, two, strict=True):
        assert np.array_equal(x, y, equal_nan=True)


