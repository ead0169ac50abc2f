"""Dexterity with error bars (issue 16 item 2): the RQMC estimator against independent answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from kinematics.analyses.dexterity import conditioning_grid, dexterity, indices
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot

from .test_cli import run, run_json


@pytest.fixture(scope="module")
def scara():
    return mechanism_of(load_robot("scara"))


@pytest.fixture(scope="module")
def p2us():
    return mechanism_of(load_robot("p2us"))


def scara_exact(sp, elbow: str) -> tuple[float, float]:
    """GCI and mean Yoshikawa index of one elbow by a 1D quadrature in joint space.

    Within one elbow (theta2 of one sign) the map (theta1, theta2) -> tip is one-to-one (theta1's
    range is under 360 deg, and r grows monotonically as |theta2| falls), with area element
    l1 l2 |sin theta2| dtheta1 dtheta2; kappa and w depend on theta2 only, so theta1 integrates
    out. Singular values from the 2x2 invariants, not an SVD: sigma1^2 + sigma2^2 = |J|_F^2 =
    l1^2 + 2 l2^2 + 2 l1 l2 cos theta2, sigma1 sigma2 = |det J| = l1 l2 |sin theta2|.
    """
    l1, l2 = sp.l1, sp.l2
    lo, hi = (sp.lower[1], 0.0) if elbow == "up" else (0.0, sp.upper[1])

    def inv_kappa(t):
        F = l1**2 + 2 * l2**2 + 2 * l1 * l2 * math.cos(t)
        D = l1 * l2 * abs(math.sin(t))
        disc = math.sqrt(max(F * F - 4 * D * D, 0.0))
        return math.sqrt((F - disc) / (F + disc))

    area = integrate.quad(lambda t: abs(math.sin(t)), lo, hi, epsabs=1e-13)[0]
    gci = integrate.quad(lambda t: inv_kappa(t) * abs(math.sin(t)), lo, hi, epsabs=1e-13, limit=200)[0] / area
    w = l1 * l2 * integrate.quad(lambda t: math.sin(t) ** 2, lo, hi, epsabs=1e-13)[0] / area
    return gci, w


def test_scara_gci_against_joint_space_quadrature(scara):
    exact = {e: scara_exact(scara.params, e) for e in ("up", "down")}
    # the area too: (upper1 - lower1) l1 l2 (1 - cos theta2_limit)
    span = scara.params.upper[0] - scara.params.lower[0]
    d = dexterity(scara, samples=1 << 14, replicates=8, seed=3)
    for k, e in enumerate(("up", "down")):
        gci, w = exact[e]
        area = span * scara.params.l1 * scara.params.l2 * (1 - math.cos(scara.params.upper[1] if e == "down"
                                                                         else scara.params.lower[1]))
        # 95 % half-widths: each of the three checks fails with probability ~5 % if the error bar
        # is right; widened x1.5 (t quantile -> ~99.7 % for a normal), so a false failure is rare
        assert abs(d.gci[k] - gci) <= 1.5 * d.gci_error[k]
        assert abs(d.yoshikawa[k] - w) <= 1.5 * d.yoshikawa_error[k]
        assert abs(d.volume[k] - area) <= 1.5 * d.volume_error[k]
        # and the error bars are informative: under 1 % of the value
        assert d.gci_error[k] < 0.01 * gci and d.yoshikawa_error[k] < 0.01 * w
    assert not d.yoshikawa_diverges.any() and not d.yoshikawa_heavy_tail.any()
    assert d.yoshikawa_unit == "m^2/rad^2"


def test_scara_error_bar_coverage(scara):
    # 20 independent runs (seeds): a 95 % interval covers the truth in each with p = 0.95, so
    # >= 16 of 20 fail only with probability P(Binomial(20, 0.95) <= 15) = 3e-3
    gci, _ = scara_exact(scara.params, "up")
    covered = 0
    for seed in range(20):
        d = dexterity(scara, ["up"], samples=1 << 11, replicates=6, seed=100 + seed)
        covered += abs(d.gci[0] - gci) <= d.gci_error[0]
    assert covered >= 16


def test_same_seed_same_numbers_and_union_is_best_branch(scara):
    a = dexterity(scara, samples=1 << 10, replicates=3, seed=7)
    b = dexterity(scara, samples=1 << 10, replicates=3, seed=7)
    assert np.array_equal(a.gci, b.gci) and np.array_equal(a.yoshikawa, b.yoshikawa)
    c = dexterity(scara, samples=1 << 10, replicates=3, seed=8)
    assert not np.array_equal(a.gci, c.gci)
    # the union covers more area than either elbow; the elbows overlap (both reach the middle)
    assert a.volume[2] > max(a.volume[:2]) and a.volume[2] < a.volume[0] + a.volume[1]


def test_p2us_gci_against_plain_monte_carlo(p2us):
    """Mode --- of paper B's design against an independent path: plain Monte Carlo over the box
    with the NumPy closed forms' IK flags and numpy.linalg.cond of J (not the mechanism's SVD)."""
    from kinematics.mechanisms.p2us.closed_form import MODES, ik, jacobians

    d = dexterity(p2us, ["---"], samples=1 << 14, replicates=8, seed=1)
    rng = np.random.default_rng(11)
    lo, hi = p2us.bounding_box()
    k = MODES.index("---")
    vals = []
    for _ in range(8):
        p = lo + (hi - lo) * rng.random((1 << 15, 3))
        res = ik(p2us.params, p)
        ok = res.within_limits[:, k]
        J = jacobians(p2us.params, p[ok], res.q[ok, k]).J
        vals.append(1 / np.linalg.cond(J))
    x = np.concatenate(vals)
    mc, se = x.mean(), x.std(ddof=1) / math.sqrt(len(x))
    # two independent estimates: their difference has sd sqrt(se_a^2 + se_b^2); the RQMC error is
    # a 95 % half-width (t_{0.975,7} = 2.36 se); allow 3 sd of the difference
    assert abs(d.gci[0] - mc) <= 3 * math.hypot(d.gci_error[0] / 2.36, se)
    assert d.gci_error[0] < 0.05 * d.gci[0]
    # paper B's design reaches type II poses at the edge of its workspace: w is tail-dominated
    assert d.yoshikawa_heavy_tail[0] and not math.isfinite(d.yoshikawa_error[0])


def test_conditioning_grid_matches_pointwise(scara):
    axes, g = conditioning_grid(scara, "up", step=0.05)
    i, j = np.argwhere(np.isfinite(g))[len(np.argwhere(np.isfinite(g))) // 2]
    p = np.array([[axes[0][i], axes[1][j]]])
    v, ok = scara.branch_velocity(p, "up")
    assert ok[0] and g[i, j] == pytest.approx(1 / np.linalg.cond(v.J[0]), rel=1e-12)
    assert np.nanmax(g) <= 1 and np.nanmin(g) >= 0


# -- CLI ------------------------------------------------------------------------------------------
def test_cli_dexterity(capsys, tmp_path):
    png, html = tmp_path / "k.png", tmp_path / "k.html"
    code, d, _ = run_json(capsys, "dexterity", "delta", "--samples", "1024", "--replicates", "3", "--seed", "2",
                          "--step", "0.1", "--plot", str(png), "--export", str(html))
    assert code == 0
    assert {"gci", "gci_error", "yoshikawa_mean", "yoshikawa_error", "modes", "samples", "seconds"} <= set(d)
    assert 0 < d["gci"] <= 1 and d["gci_error"] > 0 and d["samples"] == 1024 and len(d["modes"]) == 8
    assert png.stat().st_size > 10_000 and "MeshCat.Viewer" in html.read_text()
    code, d1, _ = run_json(capsys, "dexterity", "scara", "--mode", "up", "--samples", "1024", "--replicates", "3")
    assert code == 0 and list(d1["modes"]) == ["up"] and d1["target"] == "up"
    # a working-mode label that looks like an option is a value
    code, d2, _ = run_json(capsys, "dexterity", "p2us", "--mode", "---", "--samples", "256", "--replicates", "2")
    assert code == 0 and d2["target"] == "---"
    code, _, err = run(capsys, "dexterity", "scara", "--mode", "sideways")
    assert code == 2 and "sideways" in err
    code, _, err = run(capsys, "dexterity", "scara", "--replicates", "1")
    assert code == 2 and "replicates" in err


def test_a_sliver_gets_no_error_bar(p2us):
    # few points and a replicate without any: the spread of the others says nothing, so no bar
    d = dexterity(p2us, ["---"], samples=16, replicates=4, seed=0)
    assert d.inside[0] < 16 and not math.isfinite(d.gci_error[0])


def test_indices_against_their_definitions():
    """`indices` per Jacobian against the definitions computed another way: 1/kappa =
    1/numpy.linalg.cond, w = sqrt(det(J J^T)) by the determinant (not the singular values), the
    smallest radius = sqrt of the smallest eigenvalue of J J^T (eigvalsh); rounding ~1e-15 relative
    on these O(1) well-conditioned matrices, 1e-10 allowed (the eigenvalue route squares the
    condition number). A NaN row gives (0, inf, 0), a wide-row J (a < d) w = radius = 0, a zero J 1/kappa = 0."""
    rng = np.random.default_rng(3)
    J = rng.normal(size=(5, 2, 3, 3))
    J[1, 0, 2, 2] = np.nan
    J[4, 1] = 0.0
    inv, w, rad = indices(J)
    good = np.ones((5, 2), bool)
    good[1, 0] = good[4, 1] = False
    G = J[good] @ np.swapaxes(J[good], -1, -2)
    assert np.allclose(inv[good], 1 / np.linalg.cond(J[good]), rtol=1e-10, atol=0)
    assert np.allclose(w[good], np.sqrt(np.linalg.det(G)), rtol=1e-10, atol=0)
    assert np.allclose(rad[good], np.sqrt(np.linalg.eigvalsh(G)[:, 0]), rtol=1e-10, atol=0)
    assert (inv[1, 0], w[1, 0], rad[1, 0]) == (0.0, np.inf, 0.0) and inv[4, 1] == 0.0
    inv2, w2, rad2 = indices(rng.normal(size=(4, 3, 2)))
    assert np.all(w2 == 0.0) and np.all(rad2 == 0.0) and np.all(inv2 > 0)


@pytest.mark.parametrize("argv", [("dexterity", "scara", "--samples", "64", "--replicates", "2"),
                                  ("synthesize", "p2us", "--param", "b=0.15:0.3", "--population", "4",
                                   "--generations", "1", "--workers", "1")])
def test_cli_negative_seed_is_bad_input(capsys, argv):
    # numpy's SeedSequence takes only non-negative integers: a negative --seed is refused in one
    # line (exit 2) before any work, not a traceback from the scrambling or the search
    code, out, err = run(capsys, *argv, "--seed", "-1")
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "seed" in err and "-1" in err


def test_cli_failing_map_leaves_no_cells_file(capsys, tmp_path):
    # the map's grid at 1e-7 m is refused (over the point limit) after the indices are measured;
    # the per-cell table, ready before it, must not be left written by a command that fails
    cells, png = tmp_path / "c.csv", tmp_path / "k.png"
    code, _, err = run(capsys, "dexterity", "scara", "--samples", "64", "--replicates", "2", "--cells", "3",
                       "--cells-out", str(cells), "--plot", str(png), "--step", "1e-7")
    assert code == 2 and "step" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("samples", [math.nan, 0, 15.5])
def test_a_sample_count_below_16_or_nan_is_refused(scara, samples):
    """NaN passed the `samples < 16` test and failed in math.ceil (a ValueError)."""
    from kinematics.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match="samples"):
        dexterity(scara, samples=samples, replicates=2)
