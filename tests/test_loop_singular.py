"""Singular fields and loci of a closed loop through the generic path (no closed forms) against the
closed forms of the 3-[P2(US)] and of the Delta: the same type I limbs, the same type II / III loci."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses.singularities import singular_loci
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop
from kinematics.model.robot import load_robot


@pytest.fixture(scope="module", params=["p2us", "delta"])
def both(request):
    robot = load_robot(request.param)
    closed = mechanism_of(robot)
    generic = GenericClosedLoop(robot)
    # the same grid for both scans: the closed form's proved box (the generic one is sampled)
    generic.bounding_box = closed.bounding_box  # type: ignore[method-assign]
    return closed, generic


def test_fields_agree_with_the_closed_forms(both):
    closed, generic = both
    lo, hi = closed.bounding_box("actuators")
    p = lo + (hi - lo) * np.random.default_rng(31).random((600, 3))
    g = generic.singular_fields(p, "actuators")
    c = closed.singular_fields(p, "actuators")
    assert g.limb.shape == (600, 3) and g.det.shape == (600, 8)
    # every labelling block is evaluable everywhere: block 0 carries the platform, the others are
    # solved against the platform placed at the target (translational: pinned)
    assert np.isfinite(g.limb).all()
    # labelling block k holds actuator k: its field has the sign of limb k's IK discriminant,
    # away from the locus itself (|disc| > 1e-6 m^2, far above both paths' rounding)
    for k in range(3):
        ok = np.abs(c.limb[:, k]) > 1e-6
        assert ok.sum() > 550
        assert np.array_equal(g.limb[ok, k] >= 0, c.limb[ok, k] >= 0), k
        assert 50 < (c.limb[:, k] < 0).sum() < 550, "the sample must see limb k reach and not reach"
    both_in = (g.limb >= 0).all(axis=1) & (c.limb >= 0).all(axis=1)
    assert 50 < both_in.sum() < 550, "the sample must see points inside and outside the limbs' reach"
    # type II: each generic branch's det has the sign of one closed-form mode's, up to a constant
    # sign per branch, at every point clear of the locus (a one-to-one map of branches to modes)
    matched = []
    for b in range(8):
        ok = np.isfinite(g.det[:, b])
        assert ok.sum() > 50
        agree = []
        for m in range(8):
            sel = ok & (np.abs(c.det[:, m]) > 1e-3)
            agree.append(float(np.mean(np.sign(g.det[sel, b]) == np.sign(c.det[sel, m]))))
        exact = [m for m in range(8) if agree[m] in (0.0, 1.0)]
        assert len(exact) == 1, agree
        matched.append(exact[0])
    assert sorted(matched) == list(range(8))
    assert np.array_equal(g.margin.max(axis=1) >= 0, c.margin.max(axis=1) >= 0)


def test_singular_loci_by_type_match_the_closed_forms(both):
    """On one grid the sign changes happen on the same edges wherever both fields are defined.
    Type I: the same count per limb, and on the workspace boundary, for every limb (limbs 2 and 3
    close to a platform that hangs on limb 1 in the URDF tree; it is placed at the target, so
    their loci are found where limb 1 does not reach too). Type II / III: every generic point is a
    closed-form one; the 3-[P2(US)]'s counts are equal, the Delta's generic scan misses a few
    edges (measured: 14 of 2,780 points at 0.1 m), at grid points where a branch's basin is missed
    (the search limit of `kinematics.generic.loop_batch`) or beside a limb's reach boundary."""
    from scipy.spatial import cKDTree

    closed, generic = both
    kw = {"step": 0.05 if closed.name.startswith("p2us") else 0.1, "limits": "actuators"}
    c = singular_loci(closed, **kw)
    g = singular_loci(generic, **kw)
    cs, gs = c.summary(), g.summary()
    assert gs["type_I"] == cs["type_I"]
    for limb in range(3):
        cl = (c.locus.kind == 1) & (c.locus.which == limb)
        gl = (g.locus.kind == 1) & (g.locus.which == limb)
        assert gl.sum() == cl.sum() > 0 and (gl & g.locus.inside).sum() == (cl & c.locus.inside).sum() > 0
    sel_c = c.locus.kind >= 2
    sel_g = g.locus.kind >= 2
    assert cs["type_II"]["locus_points"] > 0 and cs["type_III"]["locus_points"] > 0
    if closed.name.startswith("p2us"):
        assert gs["type_II"] == cs["type_II"] and gs["type_III"] == cs["type_III"]
        assert cs["type_III"]["inside_workspace"] > 0  # the strokes-only workspace meets type III loci
    else:
        assert 0.99 * sel_c.sum() <= sel_g.sum() <= sel_c.sum()
        assert gs["type_II"]["inside_workspace"] == cs["type_II"]["inside_workspace"]
    # the same edges, the same points: both fields are the normalised determinant of the rows n_i
    # (the inverse Jacobian's) from joint values solved to 1e-12 m, so the interpolated crossings
    # agree to ~1e-12 m x step / |field difference|; 1e-6 m leaves room for nearly flat edges
    d, _ = cKDTree(c.locus.points[sel_c]).query(g.locus.points[sel_g])
    assert np.all(d <= 1e-6), d.max()


def test_cli_singularities_of_a_generic_spatial_loop(capsys, tmp_path):
    """`kinematics singularities MODEL.urdf` for a closed loop without closed forms: the 3-[P2(US)]
    written by the generator with its sidecar's `mechanism:` line removed (so nothing dispatches to
    the closed forms). With the strokes only, type III loci cross its workspace (as the closed
    forms find on any grid: the passive-joint limits are what keep them out)."""
    from kinematics.cli.app import main

    from .test_cli import run_json

    urdf = tmp_path / "p2g.urdf"
    assert main(["urdf", "p2us", "-o", str(urdf)]) == 0
    capsys.readouterr()
    sidecar = tmp_path / "p2g.loops.yaml"
    sidecar.write_text("".join(line for line in sidecar.read_text().splitlines(keepends=True)
                               if not line.startswith("mechanism:")))
    code, d, _ = run_json(capsys, "singularities", str(urdf), "--step", "0.05", "--limits", "actuators")
    assert code == 0
    assert d["singularities"]["type_III"]["inside_workspace"] > 0
    assert d["singularities"]["type_II"]["locus_points"] > 0


def test_planar_loci_of_the_five_bar_match_its_closed_forms():
    """A planar closed loop's loci (the task space is one plane): on the generic scan's grid, type I
    crossings are the grid edges across a chain's reach circle (|P - A_i| = a_i + b_i or
    |a_i - b_i|, tests/fivebar.py), type II ones the edges where sin(phi_2 - phi_1) changes sign in
    some working mode with both chains reaching at both ends."""
    from scipy.spatial import cKDTree

    from .fivebar import FiveBar
    from .test_fivebar import FIXTURE

    robot = load_robot(FIXTURE / "robot.urdf")
    five = FiveBar.from_robot(robot)
    mech = mechanism_of(robot)
    step = 0.02
    g = singular_loci(mech, step=step, limits="all")
    assert g.locus.points.shape[1] == 2
    lo, hi = mech.bounding_box("all")
    dims = np.ceil((hi - lo) / step).astype(int) + 1
    P = np.stack(np.meshgrid(*(lo[k] + step * np.arange(dims[k]) for k in range(2)), indexing="ij"), axis=-1)
    reach = five.reach(P)

    def edges(f: np.ndarray, ok: np.ndarray) -> list[tuple[np.ndarray, ...]]:
        """(a, b, f(a), f(b)) along x, then along y, of the grid edges where f changes sign with
        both ends ok."""
        out = []
        for sa, sb in (((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
                       ((slice(None), slice(None, -1)), (slice(None), slice(1, None)))):
            hit = ((f[sa] >= 0) != (f[sb] >= 0)) & ok[sa] & ok[sb]
            out.append((P[sa][hit], P[sb][hit], f[sa][hit], f[sb][hit]))
        return out

    # type I: limb k is chain k (the tip hangs on chain 1, so chain 2's closure is measured from
    # it: where chain 1 cannot reach, chain 2's field is undefined and its edges are not scanned)
    for k in range(2):
        ok = np.ones(P.shape[:2], dtype=bool) if k == 0 else reach[..., 0] >= 0
        expected = sum(len(a) for a, *_ in edges(reach[..., k], ok))
        pts = g.locus.points[(g.locus.kind == 1) & (g.locus.which == k)]
        assert len(pts) == expected > 50
        # each crossing lies on its edge, so within one step of the circle the edge crosses
        dk = np.linalg.norm(pts - five.A[k], axis=1)
        off = np.minimum(abs(dk - five.a[k] - five.b[k]), abs(dk - abs(five.a[k] - five.b[k])))
        assert off.max() <= step
    # type II: the generic field is det of the inverse Jacobian's normalised rows, +-(P - B_i) / b_i,
    # i.e. +-sin(phi_2 - phi_1), so both interpolate to the same point (to the 1e-12 m solves'
    # rounding over a field difference of order step: 1e-6 m leaves room for nearly flat edges)
    both = (reach >= 0).all(axis=-1)
    crossings = []
    for modes in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
        s = np.full(P.shape[:2], np.nan)
        for idx in zip(*np.nonzero(both), strict=True):
            theta = five.ik(P[idx], modes)
            if theta is not None:
                phi = five.distal_angles(theta, P[idx])
                s[idx] = np.sin(phi[1] - phi[0])
        for a, b, fa, fb in edges(s, both):
            crossings.append(a + (fa / (fa - fb))[:, None] * (b - a))
    expected_pts = np.concatenate(crossings)
    got = g.locus.points[g.locus.kind >= 2]
    assert len(got) == len(expected_pts) > 50
    dist, _ = cKDTree(expected_pts).query(got)
    assert np.all(dist <= 1e-6), dist.max()
