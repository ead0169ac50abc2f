"""Dexterity over serial workspaces (issue 29, item 3a): global means and the per-cell table,
against integrals derived here in joint space."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from kinematics.analyses.dexterity import dexterity
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.scara.closed_form import ScaraParams
from kinematics.mechanisms.serial.mechanism import SerialArm
from kinematics.model.robot import load_robot

MODELS = Path(__file__).parent / "models"
L2, L3 = 0.4, 0.25  # tests/models/arm3r_revolved.urdf: upper arm and forearm [m]
PITCH, ELBOW = (-0.5, 0.8), (0.3, 1.5)  # its joint ranges [rad]; the yaw is a full turn


def _sv2(e: float) -> tuple[float, float]:
    """Singular values of the arm plane's 2R Jacobian [m/rad]: a function of the elbow e alone
    (the pitch only turns it)."""
    J = np.array([[-L3 * math.sin(e), -L3 * math.sin(e)], [L2 + L3 * math.cos(e), L3 * math.cos(e)]])
    s = np.linalg.svd(J, compute_uv=False)
    return float(s[0]), float(s[1])


def _revolved_means() -> dict[str, float]:
    """The 3R arm's exact means over W by quadrature in joint space. Every point of W has one
    configuration (pitch and elbow ranges inside (-pi/2, pi/2) and (0, pi): one elbow, rho > 0), and
    dV = |det J| dq with det J = rho L2 L3 sin e (the yaw column rho is orthogonal to the arm's
    plane, whose 2R block has determinant L2 L3 sin e); integrating the yaw out,
    int_W f dV = int int 2 pi rho L2 L3 sin e f dt de. J's singular values are rho and the 2R
    block's s1 >= s2, so w = rho L2 L3 sin e, 1/kappa = min(rho, s2) / max(rho, s1) and the
    smallest radius is min(rho, s2)."""
    from scipy.integrate import dblquad

    def rho(t: float, e: float) -> float:
        return L2 * math.cos(t) + L3 * math.cos(t + e)

    def integral(f) -> float:
        return dblquad(lambda e, t: 2 * math.pi * rho(t, e) * L2 * L3 * math.sin(e) * f(t, e), *PITCH, *ELBOW,
                       epsabs=1e-13, epsrel=1e-11)[0]

    V = integral(lambda t, e: 1.0)
    return {
        "volume_m3": V,
        "yoshikawa_mean": integral(lambda t, e: rho(t, e) * L2 * L3 * math.sin(e)) / V,
        "gci": integral(lambda t, e: min(rho(t, e), _sv2(e)[1]) / max(rho(t, e), _sv2(e)[0])) / V,
        "smallest_radius_mean": integral(lambda t, e: min(rho(t, e), _sv2(e)[1])) / V,
    }


@pytest.fixture(scope="module")
def revolved_dex():
    return dexterity(SerialArm(load_robot(MODELS / "arm3r_revolved.urdf")), samples=1 << 14, replicates=8, seed=3,
                     cells=6)


def test_revolved_3r_means_within_their_error_bars(revolved_dex):
    exact = _revolved_means()
    assert exact["volume_m3"] == pytest.approx(0.331334, abs=1e-6)  # the docs' shell-segment test arm
    d = revolved_dex.as_dict()
    assert d["target"] == "union" and d["modes"] == {} and "search" in d["configurations"]
    assert d["yoshikawa_unit"] == "m^3/rad^3" and not d["mixed_units"]
    for key, err in (("gci", "gci_error"), ("yoshikawa_mean", "yoshikawa_error"),
                     ("smallest_radius_mean", "smallest_radius_error"), ("volume_m3", "volume_m3_error")):
        # the 95 % half-width holds, and is informative (a few per cent at most)
        assert abs(d[key] - exact[key]) <= d[err] <= 0.03 * exact[key], key
    assert d["kappa_harmonic_mean"] == pytest.approx(1 / d["gci"], rel=1e-12)


def test_revolved_3r_cells_hold_their_points(revolved_dex):
    """Each cell's mean Yoshikawa index lies within the range w = rho L2 L3 sin e takes over the
    cell: rho within the cell's distances to the z axis, e from the distance r to the shoulder
    (cos e = (r^2 - L2^2 - L3^2) / (2 L2 L3), sin e decreasing in r over the elbow range)."""
    cells = revolved_dex.cells
    assert cells is not None and len(cells.index) > 20
    lo = cells.grid.origin + cells.index * cells.grid.step
    hi = lo + cells.grid.step
    shoulder = np.array([0.0, 0.0, 0.3])

    def dist_range(a, b, centre):
        near = np.sqrt((np.maximum(0, np.maximum(a - centre, centre - b)) ** 2).sum(axis=1))
        far = np.sqrt((np.maximum(np.abs(a - centre), np.abs(b - centre)) ** 2).sum(axis=1))
        return near, far

    rho_lo, rho_hi = dist_range(lo[:, :2], hi[:, :2], np.zeros(2))
    r_lo, r_hi = dist_range(lo, hi, shoulder)

    def sin_e(r):
        c = np.clip((r**2 - L2**2 - L3**2) / (2 * L2 * L3), math.cos(ELBOW[1]), math.cos(ELBOW[0]))
        return np.sqrt(1 - c * c)

    top = rho_hi * L2 * L3 * sin_e(r_lo)
    bottom = rho_lo * L2 * L3 * sin_e(r_hi)
    assert np.all(cells.yoshikawa <= top * (1 + 1e-12)) and np.all(cells.yoshikawa >= bottom * (1 - 1e-12))
    # the table's rows carry the same numbers, and the cells' measures add up to the volume
    rows = revolved_dex.as_dict()["cells"]["rows"]
    assert [r["yoshikawa_mean"] for r in rows] == pytest.approx(cells.yoshikawa.tolist(), rel=1e-15)
    assert sum(r["volume_m3"] for r in rows) == pytest.approx(revolved_dex.volume[-1], rel=1e-12)


def test_scara_serial_path_agrees_with_closed_forms(scara):
    """The SCARA through its closed-form elbows (best elbow per point) and as a generic serial arm
    (best over the configurations the search finds): two independent paths to the same means.
    Both elbows have the same indices at a point (|sin t2| and the 2R block's singular values
    depend on |t2| alone), so the search's choice of elbow does not matter."""
    closed = dexterity(mechanism_of(scara), samples=1 << 13, replicates=8, seed=1).as_dict()
    serial = dexterity(SerialArm(scara), samples=1 << 13, replicates=8, seed=2).as_dict()
    assert "search" in serial["configurations"] and "branch" in closed["configurations"]
    for key, err in (("gci", "gci_error"), ("yoshikawa_mean", "yoshikawa_error"),
                     ("smallest_radius_mean", "smallest_radius_error"), ("area_m2", "area_m2_error")):
        assert abs(closed[key] - serial[key]) <= closed[err] + serial[err], key
    # the radius at a point: sigma_min of the 2R block, below sqrt(w) = sqrt(sigma_min sigma_max)
    sp = ScaraParams.from_robot(scara)
    assert 0 < serial["smallest_radius_mean"] < math.sqrt(sp.l1 * sp.l2)


def test_redundant_arm_takes_the_best_configuration():
    """A planar 3R arm (redundant for a 2-D position): where the search reaches a point with
    several configurations, the map's 1/kappa is the largest over them, and often above that of
    the margin's own configuration."""
    from kinematics.analyses.dexterity import conditioning_grid, indices

    arm = SerialArm(load_robot(MODELS / "planar3r.urdf"))
    axes, grid = conditioning_grid(arm, "union", step=0.02)
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 2)
    J, ok = arm.reaching_jacobians(pts)
    inv = np.where(ok, indices(J)[0], -1.0)
    inside = ok[:, 0]
    assert inside.sum() > 1000 and (ok[inside, 1:].sum(axis=1) >= 2).mean() > 0.5
    np.testing.assert_array_equal(grid.reshape(-1)[inside], inv[inside].max(axis=1))
    assert np.isnan(grid.reshape(-1)[~inside]).all()
    assert (inv[inside].max(axis=1) > inv[inside, 0] * (1 + 1e-6)).mean() > 0.1  # the seeds do find better ones
