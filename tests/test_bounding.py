"""Bounding capsules of coal's shapes (kinematics.generic.bounding) and the signs-only distances
that use them (AnalyticDistances.distances(signs=True)), against coal on the meshes of ur5 and
panda; CollisionModel.distances computing chosen entries alone."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.generic.bounding import capsule_of_points
from kinematics.generic.capsules import COAL, AnalyticDistances
from kinematics.generic.collision import NEAR, CollisionModel
from kinematics.model.robot import load_robot


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances of the points p (K, 3) from the segment [a, b], written here independently."""
    ab = b - a
    L2 = float(ab @ ab)
    t = np.zeros(len(p)) if L2 == 0 else np.clip((p - a) @ ab / L2, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 60), st.floats(0.01, 10.0))
def test_fitted_capsule_holds_every_point(seed, count, stretch):
    """Every point lies within the radius of the capsule's segment (1e-12 m: the inflation), and
    the radius is tight: some point lies on the surface (within 1e-9 m)."""
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(count, 3)) * np.array([stretch, 1.0, 0.3])
    pts = pts @ np.linalg.qr(rng.normal(size=(3, 3)))[0] + rng.normal(size=3)
    centre, axis, radius, half = capsule_of_points(pts)
    assert abs(np.linalg.norm(axis) - 1.0) < 1e-12 and half >= 0.0
    d = _segment_distance(pts, centre - half * axis, centre + half * axis)
    assert d.max() <= radius
    assert d.max() >= radius - 1e-9


def _random_configurations(robot, count, rng):
    lo = np.maximum(robot.model.lowerPositionLimit, -np.pi)
    hi = np.minimum(robot.model.upperPositionLimit, np.pi)
    return rng.uniform(lo, hi, (count, robot.model.nq))


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_signs_only_distances_keep_every_sign(name, rng):
    """With signs=True every entry has coal's sign, equals coal's value wherever it is <= 0 and is
    at most coal's elsewhere (a lower bound; 1e-9 m: coal's GJK tolerance is 1e-10), while coal
    is asked for a minority of the mesh pairs: the bounding capsules prove the rest apart
    (ur5 84 %, panda ~90 % at random configurations; without the bounds every mesh pair is
    coal's, and this count fails). Entries at or above collision.NEAR where coal's value is
    not: only a mesh pair apart by its hulls, whose distance is the hulls' (below the meshes')."""
    robot = load_robot(name)
    cm = CollisionModel.from_robot(robot)
    ad = AnalyticDistances(cm)
    q = _random_configurations(robot, 300, rng)
    exact = cm.distances(q)
    signs = ad.distances(q, signs=True)
    assert (np.sign(signs) == np.sign(exact)).all()
    low = signs <= 0
    assert low.sum() > 0 and np.abs(signs[low] - exact[low]).max() < 1e-12
    assert (signs <= exact + 1e-9).all()
    asked = []
    original = cm.distances

    def counting(q, only=None, where=None, near=False):
        asked.append(int(where.sum()) if where is not None else len(q) * len(cm.pairs))
        return original(q, only=only, where=where, near=near)

    cm.distances = counting  # type: ignore[method-assign]
    ad.distances(q, signs=True)
    mesh = int((ad.kinds == COAL).sum()) * len(q)
    assert 0 < sum(asked) < 0.3 * mesh
    # one pair per configuration: the same entries
    pair = rng.integers(0, len(cm.pairs), len(q))
    one = ad.pair_distances(q, pair, signs=True)
    assert (np.sign(one) == np.sign(exact[np.arange(len(q)), pair])).all()


def test_chosen_entries_alone_equal_the_full_evaluation(ur5, rng):
    """CollisionModel.distances(where=...) on the ur5's meshes: the chosen entries equal the full
    evaluation's (the same coal calls: 1e-12 m), the others NaN; `only` likewise by pair."""
    cm = CollisionModel.from_robot(ur5)
    q = _random_configurations(ur5, 60, rng)
    full = cm.distances(q)
    where = rng.random(full.shape) < 0.3
    part = cm.distances(q, where=where)
    assert np.isnan(part[~where]).all()
    assert np.abs(part[where] - full[where]).max() < 1e-12
    only = np.array([0, 15])
    alone = cm.distances(q, only=only)
    assert np.abs(alone[:, only] - full[:, only]).max() < 1e-12
    assert np.isnan(np.delete(alone, only, axis=1)).all()


def test_near_clamps_mesh_distances_above_near(ur5, rng):
    """near=True: every entry below NEAR is the exact path's (the same coal calls), every entry at
    or above it is NEAR (meshes' hulls overlap: the clamp) or the exact path's (hulls apart: their
    distance), and the clamp is used (39 entries at these 60 configurations are clamped; none
    without the clamp)."""
    cm = CollisionModel.from_robot(ur5)
    q = _random_configurations(ur5, 60, rng)
    exact = cm.distances(q)
    near = cm.distances(q, near=True)
    below = exact < NEAR
    assert below.any() and np.abs(near[below] - exact[below]).max() < 1e-12
    clamped = near[~below] == NEAR
    assert (clamped | (np.abs(near[~below] - exact[~below]) < 1e-12)).all()
    assert clamped.sum() >= 20
