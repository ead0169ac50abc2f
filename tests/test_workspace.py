"""Scan kernel vs the NumPy closed forms, the adaptive volume estimator, workspaces, singular loci."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from kinematics.analyses import cells as volume
from kinematics.analyses.cells import adaptive_volume, simplex_fraction
from kinematics.analyses.singularities import singular_loci
from kinematics.analyses.workspace import measure_workspace, volume_monte_carlo
from kinematics.errors import InvalidInputError, UnknownChoiceError, UnknownModeError
from kinematics.mechanisms.p2us.closed_form import MODES, ik, jacobians, limb_ik
from kinematics.mechanisms.p2us.mechanism import P2US
from kinematics.mechanisms.p2us.paper_scan import paper_scan
from kinematics.mechanisms.p2us.scan import bounding_box, scan
from kinematics.mechanisms.scara.closed_form import ScaraParams
from kinematics.mechanisms.scara.joint_space import area_quadrature, singular_set
from kinematics.mechanisms.scara.mechanism import Scara


def _box_points(params, n, rng):
    lo, hi = bounding_box(params)
    return lo + (hi - lo) * rng.random((n, 3))


# -- the fused kernel ------------------------------------------------------------------------------
@pytest.mark.parametrize("limits", ["all", "actuators"])
def test_kernel_matches_numpy_closed_forms(p2us_params, rng, limits):
    P = p2us_params
    p = _box_points(P, 200_000, rng)
    r = scan(P, p, limits)
    sol = ik(P, p, limits=limits == "all")
    clear = np.abs(r.margin) > 1e-9  # rounding may flip points exactly on a boundary
    assert clear.mean() > 0.999
    assert np.array_equal((r.margin >= 0)[clear], sol.within_limits[clear])
    assert sol.within_limits.any(), "the sample must contain workspace points"
    limbs = limb_ik(P, p)
    disc = (limbs.axis_distance**2 - P.L**2) * -1  # A^2 - G = L^2 - dist^2
    np.testing.assert_allclose(r.disc, disc, atol=1e-12)
    reach = sol.reachable[:, 0]
    for m, mode in enumerate(MODES):
        jac = jacobians(P, p[reach], sol.q[reach, m])
        n = jac.Jx / P.L  # rows r_i = L n_i
        np.testing.assert_allclose(r.det[reach, m], np.linalg.det(n), atol=1e-12)
        np.testing.assert_allclose(np.abs(r.det[reach, m]), jac.iota_II, atol=1e-12)


def test_kernel_margin_is_continuous(p2us_params, rng):
    P = p2us_params
    p = _box_points(P, 20_000, rng)
    dp = rng.normal(size=p.shape)
    dp *= 1e-7 / np.linalg.norm(dp, axis=1, keepdims=True)
    a, b = scan(P, p).margin, scan(P, p + dp).margin
    assert np.max(np.abs(a - b)) < 1e-5  # Lipschitz-like: no jumps at wrap-arounds or root swaps


def test_kernel_rejects_unknown_limits(p2us_params):
    with pytest.raises(UnknownChoiceError, match="actuators"):
        scan(p2us_params, np.zeros((1, 3)), "some")


# -- the simplex fraction and the adaptive estimator ---------------------------------------------------
@pytest.mark.parametrize("d", [1, 2, 3])
def test_simplex_fraction_against_monte_carlo(d, rng):
    values = rng.normal(size=(6, d + 1))
    bary = rng.dirichlet(np.ones(d + 1), size=400_000)
    mc = (bary @ values.T >= 0).mean(axis=0)
    np.testing.assert_allclose(simplex_fraction(values), mc, atol=4e-3)
    # permutation invariance, exact one-signed answers, and ties (repeated values)
    for perm in itertools.permutations(range(d + 1)):
        np.testing.assert_allclose(simplex_fraction(values[:, perm]), simplex_fraction(values), atol=1e-14)
    assert simplex_fraction(np.ones(d + 1)) == 1.0 and simplex_fraction(-np.ones(d + 1)) == 0.0
    tied = np.array([1.0] * d + [-1.0])  # fraction (1/2)^d... of the corner cut off near the negative vertex
    assert simplex_fraction(tied) == pytest.approx(1 - 0.5**d, abs=1e-14)


def _sphere(points):
    return np.stack([1 - np.sum(points**2, axis=1), 0.25 - np.sum((points - 0.3) ** 2, axis=1)], axis=1)


def test_adaptive_volume_of_spheres():
    res = adaptive_volume(_sphere, -np.full(3, 1.1), np.full(3, 1.1), 0.1, 1e-3, progress=False)
    exact = np.array([4 / 3 * math.pi, 4 / 3 * math.pi * 0.125])
    assert res.converged
    assert np.all(res.lower <= exact) and np.all(exact <= res.upper)
    assert np.all(np.abs(res.estimate - exact) <= 2e-3 * exact)
    # the Richardson error estimate is honest here (second-order convergence)
    assert np.all(np.abs(res.estimate - exact) <= 3 * res.error + 1e-12)
    errs = [abs(lv.estimate[0] - exact[0]) for lv in res.levels]
    assert all(e1 < 0.35 * e0 for e0, e1 in itertools.pairwise(errs))
    assert res.levels[-1].points < (2.2 / res.finest_step) ** 3 / 3  # surface work, not volume work


def test_adaptive_volume_is_chunk_independent(monkeypatch):
    args = (_sphere, -np.full(3, 1.1), np.full(3, 1.1), 0.2, 1e-2)  # ~10^5 points: chunks of 37 and the default
    a = adaptive_volume(*args, progress=False)
    monkeypatch.setattr(volume, "CELL_CHUNK", 37)
    b = adaptive_volume(*args, progress=False)
    assert np.array_equal(a.estimate, b.estimate) and np.array_equal(a.lower, b.lower)
    assert a.points_evaluated == b.points_evaluated


def test_adaptive_volume_validates():
    with pytest.raises(InvalidInputError, match="step"):
        adaptive_volume(_sphere, -np.ones(3), np.ones(3), 0.0)
    with pytest.raises(InvalidInputError, match="limit"):
        adaptive_volume(_sphere, -np.ones(3), np.ones(3), 1e-4, max_points=1000)
    with pytest.raises(InvalidInputError, match="NaN"):
        adaptive_volume(lambda p: np.full((len(p), 1), np.nan), -np.ones(2), np.ones(2), 0.5)
    uniform = adaptive_volume(_sphere, -np.full(3, 1.1), np.full(3, 1.1), 0.1, None, progress=False)
    assert len(uniform.levels) == 1 and not uniform.converged


# -- workspaces ------------------------------------------------------------------------------------------
def scara_area_closed_form(sp: ScaraParams) -> float:
    """Reachable area of a planar 2R arm with symmetric joint-2 limits +/-T (T <= pi) and a
    joint-1 range W with W + 2 max(psi) < 2 pi (true for the SCARA: 220 + 97 < 360 degrees).

    Each elbow's map is one-to-one, so its area is the integral of |det J| = l1 l2 |sin t| over
    its joint range: W l1 l2 (1 - cos T). At the radius where |theta2| = t the two elbows cover
    arcs of width W offset by 2 psi(t), psi = atan2(l2 sin t, l1 + l2 c t), overlapping over
    W - 2 psi; with r dr = l1 l2 sin t dt the overlap is int_0^T (W - 2 psi) l1 l2 sin t dt. The
    union: l1 l2 [W (1 - cos T) + 2 int_0^T psi(t) sin t dt], a smooth integral (scipy quad).
    """
    from scipy.integrate import quad

    W, T = sp.upper[0] - sp.lower[0], sp.upper[1]
    assert sp.lower[1] == -T and math.pi >= T and sp.l1 > sp.l2
    assert W + 2 * math.asin(sp.l2 / sp.l1) < 2 * math.pi
    integral, _ = quad(lambda t: math.atan2(sp.l2 * math.sin(t), sp.l1 + sp.l2 * math.cos(t)) * math.sin(t),
                       0.0, T, epsabs=1e-15, epsrel=1e-13, limit=200)
    return sp.l1 * sp.l2 * (W * (1 - math.cos(T)) + 2 * integral)


def test_scara_area_two_ways(scara):
    """The adaptive estimate and the polar quadrature against the closed form. The estimator's
    Richardson error assumes second-order convergence; where the joint limits meet the
    annulus the boundary has kinks and it is first order, so its error bar is allowed a factor 3
    (the same honesty margin as on the spheres above)."""
    sp = ScaraParams.from_robot(scara)
    exact = scara_area_closed_form(sp)
    ws = measure_workspace(Scara(sp), step=0.01, rtol=1e-4, progress=False, engine="cells")
    assert ws.result.converged
    assert abs(ws.total - exact) <= 3 * ws.result.error[-1]
    assert ws.result.lower[-1] <= exact <= ws.result.upper[-1]
    # the quadrature's integrand r * (arc measure) jumps where an elbow meets its joint-2 limit,
    # so Simpson is first order there: error <= h * jump / area ~ 3e-5 m * 2.7 m / 0.97 m^2
    # ~ 8e-5 relative (h = 0.6 m / 20000); measured 1.0e-5
    assert area_quadrature(sp) == pytest.approx(exact, rel=1e-4)
    free = ScaraParams(sp.l1, sp.l2, (-math.pi, -math.pi), (math.pi, math.pi))
    ring = math.pi * ((sp.l1 + sp.l2) ** 2 - (sp.l1 - sp.l2) ** 2)
    assert area_quadrature(free) == pytest.approx(ring, rel=1e-6)
    assert measure_workspace(Scara(free), step=0.01, rtol=1e-4, progress=False, engine="cells").total == pytest.approx(ring, rel=1e-4)


@pytest.mark.parametrize("limits", ["all", "actuators"])
def test_p2us_volume_against_monte_carlo(p2us_params, limits):
    rtol = 5e-3
    ws = measure_workspace(P2US(p2us_params), step=0.02, rtol=rtol, limits=limits, progress=False, engine="cells")
    mc, se = volume_monte_carlo(P2US(p2us_params), 1_000_000, np.random.default_rng(5), limits)
    assert abs(ws.total - mc) < 4 * se + rtol * mc  # 4 standard errors + the requested rtol
    r = ws.result
    assert r.lower[-1] - 4 * se <= mc <= r.upper[-1] + 4 * se  # the bounds, checked independently
    assert ws.total >= max(r.estimate[:-1]) - 1e-12  # the union contains every mode
    assert ws.total <= sum(r.estimate[:-1]) + 1e-12


def test_p2us_workspace_modes_and_keys(p2us_params):
    ws = measure_workspace(P2US(p2us_params), step=0.03, rtol=None, branches=["---", "+++"], progress=False, engine="cells")
    d = ws.as_dict()
    assert set(d["modes"]) == {"---", "+++"}
    assert {"volume_m3", "bounds_m3", "modes", "bbox", "points_evaluated", "step_m", "seconds"} <= set(d)
    with pytest.raises(UnknownModeError, match=r"\+\+\+"):
        measure_workspace(P2US(p2us_params), branches=["+*+"], progress=False)


# -- singularities -------------------------------------------------------------------------------------------
def test_singular_loci_lie_on_singularities(p2us_params):
    P = p2us_params
    step = 0.02
    res = singular_loci(P2US(P), step=step, limits="actuators", progress=False)
    loc = res.locus
    assert loc.count(1) and loc.count(2) and loc.count(3)
    r = scan(P, loc.points, "actuators")
    t2 = loc.kind >= 2
    det_at = np.abs(r.det[t2, loc.which[t2]])
    assert np.median(det_at) < 0.02  # interpolated onto the locus: |det| ~ step^2 curvature
    t1 = loc.kind == 1
    iota_I = np.sqrt(np.abs(r.disc[t1, loc.which[t1]])) / P.L
    assert np.median(iota_I) < 0.05
    assert loc.interior.any()  # with only strokes, type II surfaces cross the workspace


def test_no_type_II_inside_the_limited_workspace(p2us_params):
    """Paper B: no singularity inside its joint-limited workspace (a finding, checked at 1 cm)."""
    res = singular_loci(P2US(p2us_params), step=0.01, progress=False)
    assert not res.any_inside
    assert res.summary()["type_II"]["inside_workspace"] == 0


def test_paper_scan_counts(p2us_params):
    ps = paper_scan(p2us_params)
    assert ps["actuator_triples"] == 512
    assert sum(c["all"] for c in ps["counts"].values()) == ps["poses"] == len(ps["rows"])
    loose = paper_scan(p2us_params, tol=0.05)
    assert sum(c["all"] for k, c in loose["counts"].items() if k != "none") > 0


def test_scara_singular_arc(scara):
    sp = ScaraParams.from_robot(scara)
    s = singular_set(sp, math.radians(2.0))
    assert s["theta2_zero_within_limits"] and not s["theta2_pi_within_limits"]
    r = np.hypot(*s["singular_points"].T)
    np.testing.assert_allclose(r, sp.l1 + sp.l2, atol=1e-12)
    np.testing.assert_allclose(s["singular_q"][:, 1], 0.0, atol=1e-12)
    assert len(r) == len(s["theta1"])
    assert s["min_radius"].min() == pytest.approx(0.0, abs=1e-12)


def test_scara_area_meets_requested_rtol(scara):
    """With the check run (the CLI's): at 1 cm the columns alone miss slivers near the tangencies
    (2.7e-5 m^2 below the exact area, whatever the quadrature's accuracy: 0.97289923 at rtol 1e-7),
    which only the half-step run sees; the single run's estimate covers its quadrature only."""
    sp = ScaraParams.from_robot(scara)
    ws = measure_workspace(Scara(sp), step=0.01, rtol=1e-4, progress=False, check=True)  # the column engine
    true_error = abs(ws.total - scara_area_closed_form(sp))
    # the requested tolerance is met, and the reported error is not smaller than the true one
    assert ws.result.converged and true_error <= 1e-4 * ws.total and true_error <= ws.error


def test_scara_converges_at_1e5_against_its_exact_areas():
    """Issue 29's row: `workspace-volume scara --rtol 1e-5` (1 cm columns, the check on). The 1 cm
    and 5 mm runs disagree (slivers where a joint-1 limit arc is tangent to the outer circle), so
    the check halves the step until two runs agree. Each elbow's area is exactly
    W l1 l2 (1 - cos T) (its map is one-to-one), the union's `scara_area_closed_form`; each
    estimate holds its exact value."""
    from kinematics.model.robot import load_robot

    sp = ScaraParams.from_robot(load_robot("scara"))
    elbow = (sp.upper[0] - sp.lower[0]) * sp.l1 * sp.l2 * (1 - math.cos(sp.upper[1]))
    ws = measure_workspace(Scara(sp), step=0.01, rtol=1e-5, check=True)
    r = ws.result
    assert r.converged and r.step < 0.005
    for got, err, want in zip(r.estimate, r.error, (elbow, elbow, scara_area_closed_form(sp)), strict=True):
        assert abs(got - want) <= err <= 1e-5 * want, (got, err, want)


@pytest.mark.parametrize("n", [0, -5, 1.5, 10**12, True])
def test_monte_carlo_refuses_a_sample_count_that_is_no_positive_whole_number(scara, n):
    """n = 0 was a ZeroDivisionError, -5 numpy's 'negative dimensions', 1.5 a TypeError, 1e12 an
    allocation of terabytes; each is an InvalidInputError naming n."""
    with pytest.raises(InvalidInputError, match="^n: "):
        volume_monte_carlo(Scara(ScaraParams.from_robot(scara)), n, np.random.default_rng(0))
