"""Sampled columns' root refinement shared between targets (`kinematics.analyses.columns.sampled`)."""

from __future__ import annotations

import math

import numpy as np

from kinematics.analyses.columns import Counter, column_lengths


def _jump(p: np.ndarray, radius: float) -> np.ndarray:
    """A closed loop's margin shape: a constant 1 m inside the disc, minus the distance outside."""
    r = np.linalg.norm(p, axis=1)
    return np.where(r <= radius, 1.0, radius - r)


def test_targets_that_share_a_root_share_its_refinement():
    """Three targets: two branches with the same reach (the unit disc; one's outside residual
    twice the other's, so their false-position steps differ) and their union (the larger). The
    three share every root: refined together they cost one target's evaluations (counted:
    without sharing three times as many), and each length is the single-target run's to within
    the brackets (2 x tol a column)."""

    def margin(p):
        a = _jump(p, 1.0)
        b = np.where(a > 0, 0.5, 2.0 * a)
        return np.stack([a, b, np.maximum(a, b)], axis=1)

    base = np.array([[0.0], [0.3], [0.6], [0.9], [0.99]])
    step, tol = 0.05, 1e-9
    samples = len(base) * (math.ceil(2.6 / step) + 1)
    single = Counter(2)
    ell1, _, _ = column_lengths(lambda p: _jump(p, 1.0), base, -1.3, 1.3, step, counter=single, root_tol=tol)
    both = Counter(2)
    ell, err, ends = column_lengths(margin, base, -1.3, 1.3, step, counter=both, root_tol=tol)
    for t in range(3):
        np.testing.assert_allclose(ell[:, t], ell1[:, 0], rtol=0, atol=2 * tol)
    assert np.all(err <= 2 * tol) and np.all(ends == 2)
    assert both.points - samples <= single.points - samples, (both.points, single.points)


def test_targets_with_different_roots_are_refined_separately():
    """A union of two discs (radius 1 and 0.7, the smaller one offset): in each interval where both
    change sign their brackets start together and part at the first probe between the roots;
    each length is still exact to the brackets."""

    def margin(p):
        a = _jump(p, 1.0)
        b = _jump(p - np.array([0.0, 0.25]), 0.7)
        return np.stack([a, b, np.maximum(a, b)], axis=1)

    base = np.array([[0.0], [0.2], [0.5], [0.65]])
    step, tol = 0.4, 1e-9  # wide samples: both discs' ends fall in the same intervals
    ell, err, _ = column_lengths(margin, base, -1.3, 1.3, step, root_tol=tol)
    x = base[:, 0]
    disc = 2 * np.sqrt(1 - x**2)
    small = 2 * np.sqrt(0.49 - x**2)
    np.testing.assert_allclose(ell[:, 0], disc, rtol=0, atol=2 * tol)
    np.testing.assert_allclose(ell[:, 1], small, rtol=0, atol=2 * tol)
    # the union: the unit disc's chord, with the small disc's part above it added
    top = np.maximum(np.sqrt(1 - x**2), 0.25 + np.sqrt(0.49 - x**2))
    np.testing.assert_allclose(ell[:, 2], top + np.sqrt(1 - x**2), rtol=0, atol=2 * tol)
    assert np.all(err <= 2 * tol)


def test_a_jump_with_a_linear_residual_closes_in_a_few_probes():
    """A closed loop's margin: a constant inside, minus a residual linear in the distance outside.
    The secant through two outside points is then exact, and the two probes 0.45 tol either side
    of it close the bracket: after the first false-position step (the second outside point) and
    the stall it shows, about 5 evaluations a root. Taking the secant only after a second stall,
    and bisecting a stalled bracket, cost 9.1; allowed: 6."""
    base = np.array([[0.0], [0.3], [0.6], [0.9], [0.99]])
    step, tol = 0.05, 1e-9
    counter = Counter(2)
    ell, err, _ = column_lengths(lambda p: _jump(p, 1.0), base, -1.3, 1.3, step, counter=counter, root_tol=tol)
    np.testing.assert_allclose(ell[:, 0], 2 * np.sqrt(1 - base[:, 0] ** 2), rtol=0, atol=2 * tol)
    per_root = (counter.points - len(base) * (math.ceil(2.6 / step) + 1)) / (2 * len(base))
    assert per_root <= 6, per_root
