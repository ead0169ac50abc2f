"""Collision-free exact columns (kinematics.analyses.collision_columns) against the collision
margin sampled densely along the same columns, and against the sampled route's volume."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses.collision_columns import ExactCollisionMargin
from kinematics.analyses.collision_prescan import Prescan
from kinematics.analyses.collision_volume import PRESCAN_CELLS
from kinematics.analyses.collisions import CollisionMargin, collision_model_of
from kinematics.generic.capsules import AnalyticDistances
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot


@pytest.fixture(scope="module")
def p2us_results():
    robot = load_robot("p2us-results")
    mech = mechanism_of(robot)
    dist = AnalyticDistances(collision_model_of(robot))
    lo, hi = mech.bounding_box("all")
    scan = Prescan(CollisionMargin(mech, robot, dist, ["---"], "all"), lo, hi, PRESCAN_CELLS)
    watched = np.flatnonzero(scan.counts)[:3]
    margin = CollisionMargin(mech, robot, dist, ["---"], "all", watched, prescan=scan)
    return mech, robot, dist, lo, hi, scan, watched, ExactCollisionMargin(margin, scan, 0.01, 1e-10)


def test_columns_match_the_margin_sampled_densely(p2us_results, rng, monkeypatch):
    """p2us-results (mode ---, self-collisions, three watched pairs): on 40 random columns the
    lengths of every target (the branch, the kinematic union, each watched pair alone, the union)
    match the fraction of 40001 equally spaced points where the joined margin (`CollisionMargin`,
    distances everywhere, no pre-scan) is >= 0, within 8 sample spacings (each interval end of the
    dense count is off by at most one spacing; a column has at most a few ends); and collisions
    shorten some columns by more than 5 cm (the comparison is not of the kinematic lengths alone)."""
    mech, robot, dist, lo, hi, scan, watched, margin = p2us_results
    ax = int(np.argmin(hi - lo))
    others = [k for k in range(3) if k != ax]
    base = lo[others] + (hi[others] - lo[others]) * rng.random((40, 2))
    length, err, _, _, _ = margin.exact_columns(base, ax, lo[ax], hi[ax])
    plain = CollisionMargin(mech, robot, dist, ["---"], "all", watched)
    zs = np.linspace(lo[ax], hi[ax], 40001)
    dz = zs[1] - zs[0]
    ref = np.zeros_like(length)
    for i, (u, v) in enumerate(base):
        p = np.empty((len(zs), 3))
        p[:, others[0]], p[:, others[1]], p[:, ax] = u, v, zs
        ref[i] = (plain(p) >= 0).sum(axis=0) * dz
    assert np.abs(ref - length).max() <= 8 * dz
    assert (length[:, 1] - length[:, -1]).max() > 0.05  # the kinematic union less the collision-free one
    assert np.all(err >= 0) and err.max() < 1e-6
    import kinematics.analyses.collision_columns as cc

    monkeypatch.setattr(cc, "CHUNK_COLUMNS", 16)  # in batches of 16 columns: the same columns
    chunked = margin.exact_columns(base, ax, lo[ax], hi[ax])
    assert np.array_equal(chunked[0], length) and np.array_equal(chunked[1], err)


def test_a_pair_dipping_into_contact_inside_a_root_gap_is_seen(p2us_results):
    """p2us-results, mode ---, no watched pair, first samples 8 cm apart (the CLI's: SPACING x
    1 cm): along the column at (0.11457, -0.06103) m, limb_2 - rod_3_1 collides over z -0.5300 to
    -0.4582 m, 2 mm free, then limb_1 - rod_3_1 from -0.4561 m. A gap from -0.5305 m (limb_2 -
    rod_3_1 clear by 0.2 mm) to -0.4533 m (limb_1 - rod_3_1 colliding) changes sign, its root is
    sought on limb_1 - rod_3_1 and lands at -0.4561 m, where every pair is clear: the collision of
    limb_2 - rod_3_1 inside the gap was missed (the union 7.2 cm too long, on 404 of 40,000
    columns of a grid) until a pair clear at both ends of such a gap had to be proven clear over
    it. The union's length against the joined margin at 40,001 points (each end off by at most a
    spacing; 6 ends), at that column and its mirror image in x."""
    mech, robot, dist, lo, hi, scan, _, _ = p2us_results
    margin = ExactCollisionMargin(CollisionMargin(mech, robot, dist, ["---"], "all", [], prescan=scan), scan,
                                  0.08, 1e-10)
    base = np.array([[0.11457286432160807, -0.06102961484627262], [-0.11457286432160807, -0.06102961484627262]])
    length = margin.exact_columns(base, 2, lo[2], hi[2])[0][:, -1]
    plain = CollisionMargin(mech, robot, dist, ["---"], "all")
    zs = np.linspace(lo[2], hi[2], 40001)
    dz = zs[1] - zs[0]
    for (u, v), got in zip(base, length, strict=True):
        ref = (plain(np.column_stack([np.full(len(zs), u), np.full(len(zs), v), zs]))[:, -1] >= 0).sum() * dz
        assert abs(got - ref) <= 6 * dz
        assert 0.25 < ref < 0.27  # the column's collision-free length (0.2602 m): the case is the one above


@pytest.mark.slow
def test_volume_matches_the_sampled_route_at_a_finer_step(p2us_results):
    """The collision-free volume of p2us-results (mode ---) in the slab -0.4 <= z <= -0.28 m of
    its workspace box (collisions remove most of it), by the exact columns at step 0.02 m and by
    the sampled route (sampled columns of the joined margin) at step 0.005 m, both at rtol 1e-2:
    equal within the sum of their error estimates, and the two binding pairs' removals likewise.
    (The sampled route at step 0.02 m, 7 samples per column here, misses pieces thinner than the
    step: 2.5 % low, beyond its estimate.)"""
    from kinematics.analyses.collision_volume import measure_collision_workspace

    mech, robot, _, lo, hi, _, _, _ = p2us_results
    box = (np.array([lo[0], lo[1], -0.4]), np.array([hi[0], hi[1], -0.28]))
    a, b = (measure_collision_workspace(mech, robot, step=step, rtol=1e-2, branches=["---"], check=False, box=box,
                                        watch=2, exact=exact) for step, exact in ((0.02, True), (0.005, False)))
    assert a.removed > 0.5 * a.kinematic  # collisions bind in this slab
    assert abs(a.workspace.total - b.workspace.total) <= a.workspace.error + b.workspace.error
    assert abs(a.kinematic - b.kinematic) <= a.kinematic_error + b.kinematic_error
    assert len(a.pairs) == 2
    for p, q in zip(a.pairs, b.pairs, strict=True):
        assert p.links == q.links and abs(p.removed - q.removed) <= p.error + q.error


def test_roots_on_one_pair_are_the_roots_on_every_pair(p2us_results, rng, monkeypatch):
    """The collision ends refined on one pair's distance (`PAIR_ROOTS`: its two shapes alone, the
    smallest distance's root checked by one full evaluation at the bracket's free end) are those
    refined on the targets' functions with every pair evaluated: on 200 random columns of
    p2us-results every target's length agrees within 2 brackets (1e-10 m) per end, and the
    signatures (which pair binds at each collision end) are the same."""
    import kinematics.analyses.collision_columns as cc

    mech, robot, dist, lo, hi, scan, watched, margin = p2us_results
    ax = int(np.argmin(hi - lo))
    others = [k for k in range(3) if k != ax]
    base = lo[others] + (hi[others] - lo[others]) * rng.random((200, 2))
    one = margin.exact_columns(base, ax, lo[ax], hi[ax])
    monkeypatch.setattr(cc, "PAIR_ROOTS", False)
    every = margin.exact_columns(base, ax, lo[ax], hi[ax])
    assert (one[0][:, 1] - one[0][:, -1]).max() > 0.05  # collisions shorten columns
    assert np.all(np.abs(one[0] - every[0]) <= 2e-10 * np.maximum(one[2], 1))
    assert np.array_equal(one[3], every[3])
