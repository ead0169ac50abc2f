"""Dimensional synthesis (issue 16 item 4): NSGA-II on Dask, the front, reproducibility, and the
usable cube the objectives rest on, checked by an independent path."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses.synthesis import (
    Bound,
    Settings,
    design,
    evaluate,
    footprint,
    gap_to_front,
    non_dominated,
    synthesize,
)
from kinematics.analyses.usable import usable
from kinematics.mechanisms import mechanism_of
from kinematics.model.robot import load_robot

from .test_cli import run_json

TINY = Settings(cube_cells=16, gci_samples=256, gci_replicates=2)
"""Coarse on purpose: these tests check the machinery, not the optimum."""


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as c:
        yield c


@pytest.fixture(scope="module")
def p2us():
    return mechanism_of(load_robot("p2us"))


@pytest.fixture(scope="module")
def delta():
    return mechanism_of(load_robot("delta"))


def test_non_dominated_by_hand():
    F = np.array([[1, 1], [2, 0], [0, 2], [2, 2], [1, 1], [1.5, 1.5]])
    # (2, 2) and (1.5, 1.5) are dominated by (1, 1); the duplicate (1, 1) rows are both kept
    assert non_dominated(F).tolist() == [0, 1, 2, 4]


def test_gap_to_front_by_hand():
    front = [{"cube_edge_m": 0.2, "gci": 0.4, "footprint_m": 0.3}, {"cube_edge_m": 0.1, "gci": 0.5, "footprint_m": 0.2}]
    worse = {"cube_edge_m": 0.15, "gci": 0.3, "footprint_m": 0.35}
    g = gap_to_front(front, worse)
    # normalised ranges: edge 0.1, gci 0.2, footprint 0.15; against row 0: max(-0.5, -0.5, -1/3) = -1/3
    assert g["dominated"] and g["epsilon"] == pytest.approx(-1 / 3) and g["closest"]["cube_edge_m"] == 0.2
    better = {"cube_edge_m": 0.3, "gci": 0.6, "footprint_m": 0.1}
    assert gap_to_front(front, better)["epsilon"] > 0 and not gap_to_front(front, better)["dominated"]


def test_designs_and_footprints(p2us, delta):
    m = design("p2us", p2us.params, {"b": 0.35, "stroke_max": 0.55})
    assert m.params.b == 0.35 and m.params.stroke == (p2us.params.stroke[0], 0.55) and footprint(m) == 0.35
    d = design("delta", delta.params, {"theta_min": 0.2, "la": 0.25})
    # the actuator range excludes the horizontal: the elbow reaches out R + la cos(0.2) at most
    assert footprint(d) == pytest.approx(delta.params.R + 0.25 * np.cos(0.2))
    assert footprint(delta) == pytest.approx(delta.params.R + delta.params.la)
    bad = evaluate("p2us", p2us.params, {"d": 0.5}, TINY)  # a platform wider than the base
    assert not bad["feasible"] and "d" in bad["reason"]


def test_synthesis_front_is_reproducible_and_non_dominated(p2us, client):
    bounds = [Bound.parse("b=0.28:0.38", "p2us"), Bound.parse("L=0.30:0.40", "p2us")]
    a = synthesize(p2us, bounds, population=4, generations=2, seed=5, settings=TINY, client=client)
    b = synthesize(p2us, bounds, population=4, generations=2, seed=5, settings=TINY, client=client)
    assert a.rows == b.rows and len(a.history) == 8 and a.rows
    # no evaluated design dominates a front row (objectives: edge up, GCI up, footprint down)
    for r in a.rows:
        for h in a.history:
            if h["feasible"]:
                ge = h["cube_edge_m"] >= r["cube_edge_m"] and h["gci"] >= r["gci"] and h["footprint_m"] <= r["footprint_m"]
                gt = h["cube_edge_m"] > r["cube_edge_m"] or h["gci"] > r["gci"] or h["footprint_m"] < r["footprint_m"]
                assert not (ge and gt)
        assert 0.28 <= r["b"] <= 0.38 and 0.30 <= r["L"] <= 0.40
    # the worker's numbers are the in-process evaluation's (deterministic objectives)
    r = a.rows[0]
    again = evaluate("p2us", p2us.params, {"b": r["b"], "L": r["L"]}, TINY)
    assert again["cube_edge_m"] == r["cube_edge_m"] and again["gci"] == r["gci"]
    assert a.to_csv().splitlines()[0] == "b,L,cube_edge_m,gci,footprint_m,gci_error"
    # the starting design is reported with its distance to the front
    here = evaluate("p2us", p2us.params, {}, TINY)
    assert a.reference["cube_edge_m"] == here["cube_edge_m"] and "epsilon" in a.reference["gap"]
    c = synthesize(p2us, bounds, population=4, generations=2, seed=6, settings=TINY, client=client)
    assert [h["b"] for h in c.history] != [h["b"] for h in a.history]


def delta_usable_independent(params, p: np.ndarray, kappa_max: float) -> np.ndarray:
    """Mode --- usable by another path: the Delta closed forms' IK limit flags (not the margin) and
    numpy.linalg.cond of the closed-form J (not the SVD of `inverse_condition`)."""
    from kinematics.mechanisms.delta.closed_form import MODES, ik, jacobians

    k = MODES.index("---")
    res = ik(params, p)
    ok = res.within_limits[:, k]
    q = np.where(ok[:, None], res.q[:, k], 0.0)
    with np.errstate(all="ignore"):
        J = jacobians(params, p, q).J
        kappa = np.linalg.cond(np.where(np.isfinite(J), J, 0.0))
    return ok & np.isfinite(kappa) & (kappa <= kappa_max)


def test_delta_usable_cube_is_inside(delta):
    kappa = 10.0
    res = usable(delta, "cube", kappa_max=kappa, step=0.08, search=False)
    assert res.size[0] > 0.1 and res.min_field >= 0
    # a dense check the optimiser never used: a 31^3 grid through the cube (spacing edge/30 ~ 8 mm,
    # five times finer than the membership test's step/2 = 40 mm) and 20 000 random points on its faces
    a = res.size[0] / 2
    g = np.linspace(-a, a, 31)
    solid = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    rng = np.random.default_rng(16)
    face = rng.uniform(-a, a, (20_000, 3))
    axis = rng.integers(0, 3, 20_000)
    face[np.arange(20_000), axis] = a * rng.choice([-1.0, 1.0], 20_000)
    pts = res.center + np.concatenate([solid, face])
    assert delta_usable_independent(delta.params, pts, kappa).all()
    # and the region is bounded: a cube twice as large is not usable everywhere
    assert not delta_usable_independent(delta.params, res.center + 2 * np.concatenate([solid, face]), kappa).all()


@pytest.mark.slow
def test_cli_usable_workspace_delta(capsys):
    code, d, _ = run_json(capsys, "usable-workspace", "delta", "--shape", "cube", "--step", "0.1")
    assert code == 0 and d["shape"] == "cube" and d["mode"] == "---" and d["check"]["inside"]
    assert d["volume_m3"] == pytest.approx(d["size_m"]["edge_m"] ** 3)


@pytest.mark.slow
def test_cli_synthesize(capsys, tmp_path):
    out, png = tmp_path / "front.csv", tmp_path / "front.png"
    code, d, _ = run_json(capsys, "synthesize", "delta", "--param", "la=0.25:0.35", "--param", "lb=0.7:0.9",
                          "--population", "4", "--generations", "1", "--workers", "1", "--cube-cells", "12",
                          "--gci-samples", "256", "--seed", "3", "--out", str(out), "--plot", str(png))
    assert code == 0 and d["family"] == "delta" and d["designs_evaluated"] == 4
    lines = out.read_text().splitlines()
    assert lines[0] == "la,lb,cube_edge_m,gci,footprint_m,gci_error" and len(lines) == len(d["pareto_front"]) + 1
    assert png.stat().st_size > 10_000 and {"cube_edge_m", "gci", "gap"} <= set(d["reference"])


@pytest.mark.parametrize(("bound", "error", "match"), [
    (Bound("zz", 0.1, 0.2), "UnknownParameterError", "valid: b, d, L"),
    (Bound("b", 0.3, 0.2), "InvalidInputError", "LOWER < UPPER"),
    (Bound("b", float("nan"), 0.3), "InvalidInputError", "LOWER < UPPER"),
])
def test_a_bound_is_checked_before_the_workers_start(p2us, client, bound, error, match):
    """A Bound built in Python skips Bound.parse: an unknown name failed on a worker as "a design
    failed: TypeError: P2USParams.__init__() got an unexpected keyword argument", a reversed or NaN
    range in pymoo's sampling on an `assert`."""
    import kinematics.errors as errors

    with pytest.raises(getattr(errors, error), match=match):
        synthesize(p2us, [bound], population=4, generations=1, settings=TINY, client=client)
