"""The Delta's exact columns (`kinematics.mechanisms.delta.exact`) against the sampled columns of
the same margin and against the generic closed-loop path (no closed forms)."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses.columns import column_lengths, column_volume
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot


@pytest.fixture(scope="module")
def delta():
    return mechanism_of(load_robot("delta"))


def _columns(mech, limits, ax, n, seed):
    lo, hi = mech.bounding_box(limits)
    oth = [k for k in range(3) if k != ax]
    base = lo[oth] + (hi[oth] - lo[oth]) * np.random.default_rng(seed).random((n, 2))
    return base, lo, hi


@pytest.mark.parametrize("limits", ["all", "actuators"])
def test_exact_columns_agree_with_a_sampler(delta, limits):
    """Exact columns (polynomial roots) against the margin sampled every 0.5 mm along the column and
    refined to 1e-12 m (`column_lengths`: the scan kernel's margin only, no polynomial): sampling can
    only miss components shorter than its step, so the exact length is never below the sampled one
    and equals it, to the brackets, wherever both see the same number of ends. Every axis: the
    vertical columns take the closed forms through rho^2, the others the general root finder."""
    margin = delta.margin(limits=limits)
    for ax in range(3):
        base, lo, hi = _columns(delta, limits, ax, 120, 11 + ax)
        sampled, _, s_ends = column_lengths(margin.sampled(), base, lo[ax], hi[ax], 5e-4, ax)
        exact, err, ends, _sig, zbox = margin.exact_columns(base, ax, lo[ax], hi[ax])
        same = s_ends == ends
        # brackets: <= 1e-12 m per end (sampler, <= 8 ends) plus the exact ends' own estimates
        assert np.all(np.abs(exact - sampled)[same] <= 1e-11 + err[same]), (ax, np.abs(exact - sampled)[same].max())
        assert np.all(exact >= sampled - 1e-11 - err)
        assert same.mean() > 0.97  # what differs are slivers under 0.5 mm
        assert (exact[:, -1] > 0).mean() > 0.2  # the columns do cross the workspace
        inside = exact[:, -1] > 0
        assert np.all(zbox[inside, 1] - zbox[inside, 0] >= exact[inside, -1] - 1e-12)
        assert np.all(err <= 1e-9)  # no near-tangency among these columns


def test_signatures_follow_the_ends(delta):
    """Along x at y = 0, z = -0.8: columns of equal signature have the same ends (count per target),
    the signature changes across the workspace's width (other constraints end the columns near its
    sides), and a column's signature does not depend on the batch it is computed in."""
    margin = delta.margin(limits="all")
    lo, hi = delta.bounding_box("all")
    x = np.linspace(-0.45, 0.45, 181)
    base = np.c_[x, np.full_like(x, -0.8)]
    _ell, _err, ends, sig, _ = margin.exact_columns(base, 1, lo[1], hi[1])
    assert len(set(sig.tolist())) >= 3
    for s in set(sig.tolist()):
        assert len({tuple(e) for e in ends[sig == s]}) == 1
    _ell, _err, _ends, sig2, _ = margin.exact_columns(base[::-1].copy(), 1, lo[1], hi[1])
    assert np.array_equal(sig2[::-1], sig)


def test_exact_volume_agrees_with_the_sampled_engine(delta):
    """The same union volume by exact and by sampled columns (same engine, same margin): within the
    sum of the two error estimates, at rtol 1e-2 on a coarse start."""
    lo, hi = delta.bounding_box("all")
    margin = delta.margin(["---"], "all")
    ex = column_volume(margin, lo, hi, step=0.04, rtol=1e-3)
    sa = column_volume(margin.sampled(), lo, hi, step=0.02, rtol=1e-2)
    assert ex.converged and sa.converged
    assert abs(ex.estimate[-1] - sa.estimate[-1]) <= ex.error[-1] + sa.error[-1], (ex.estimate, sa.estimate)
    assert ex.error[-1] <= 1e-3 * ex.estimate[-1] * 1.0001


@pytest.mark.slow
def test_exact_columns_against_the_generic_path(delta):
    """The generic closed-loop path (`LoopBatch`: Newton on the URDF's loop equations, no closed
    forms) sampled along a few vertical columns: with the actuator limits only the union's lengths
    agree to the generic solver's root accuracy (1e-10 m per end, two to four ends); with every
    limit the URDF bounds each ball joint by the box [-cone, cone]^2 around its cone
    (`delta.urdf`), a superset, so the exact columns are never longer."""
    from kinematics.generic.loop_batch import LoopBatch

    robot = load_robot("delta")
    lb = LoopBatch.from_robot(robot, seeds=256)
    base = np.array([[0.0, 0.0], [0.1, -0.05], [-0.2, 0.15], [0.3, 0.2], [-0.4, -0.1]])
    for limits in ("actuators", "all"):
        lo, hi = delta.bounding_box(limits)
        exact, _err, ends, _sig, _ = delta.margin(limits=limits).exact_columns(base, 2, lo[2], hi[2])
        gen, _, g_ends = column_lengths(lambda p, limits=limits: lb.margin(p, limits), base, lo[2], hi[2], 5e-3, 2)
        assert np.all(exact[:, -1] > 0.2)
        if limits == "actuators":
            assert np.array_equal(ends[:, -1], g_ends[:, -1])
            assert np.all(np.abs(exact[:, -1] - gen[:, -1]) <= 5e-10), np.abs(exact[:, -1] - gen[:, -1])
        else:
            assert np.all(exact[:, -1] <= gen[:, -1] + 5e-10)
            assert np.any(exact[:, -1] < gen[:, -1] - 1e-3)  # the cones do cut where the box does not


def test_real_roots_of_polynomials_with_known_roots():
    """`roots.real_roots` on polynomials built from their roots (up to 6 real ones at least 1e-3
    apart, or fewer times s^2 + q with q > 0 for a complex pair), on intervals that cut some roots
    off: exactly the roots inside, each to 1e-12 (the coefficients' rounding over a unit interval),
    within its own error estimate plus that."""
    from kinematics.mechanisms.delta.roots import DEG, real_roots

    rng = np.random.default_rng(5)
    out, err, ids = np.empty(64), np.empty(64), np.empty(64, np.int64)
    work, stack = np.zeros((DEG + 1, DEG + 1)), np.zeros((64, 2 * DEG + 2))
    checked = 0
    for _ in range(300):
        k = int(rng.integers(1, DEG + 1))
        while True:
            r = np.sort(rng.uniform(-1.0, 1.0, k))
            if k == 1 or np.diff(r).min() > 1e-3:
                break
        c = np.polynomial.polynomial.polyfromroots(r) * rng.uniform(0.5, 2.0) * rng.choice([-1.0, 1.0])
        if k <= DEG - 2 and rng.random() < 0.5:
            c = np.polynomial.polynomial.polymul(c, [rng.uniform(0.01, 1.0), 0.0, 1.0])
        coef = np.zeros(DEG + 1)
        coef[:len(c)] = c
        lo, hi = sorted(rng.uniform(-1.2, 1.2, 2))
        want = r[(r > lo + 1e-9) & (r < hi - 1e-9)]
        if np.any(np.abs(r - lo) <= 1e-9) or np.any(np.abs(r - hi) <= 1e-9):
            continue
        n = real_roots(coef, lo, hi, out, err, ids, 0, 3, work, stack)
        got = np.sort(out[:n])
        assert n == len(want), (r, lo, hi, got)
        assert np.all(np.abs(got - want) <= 1e-12 + err[:n][np.argsort(out[:n])]), (got - want, err[:n])
        assert np.all(ids[:n] == 3)
        checked += n
    assert checked > 200
