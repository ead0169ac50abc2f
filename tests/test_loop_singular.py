"""Singular fields and loci of a closed loop through the generic path (no closed forms) against the
3-[P2(US)]'s closed forms: the same type I limbs, the same type II / III loci."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.analyses.singularities import singular_loci
from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.closed_loop.mechanism import GenericClosedLoop
from kinematics.model.robot import load_robot


@pytest.fixture(scope="module")
def both():
    robot = load_robot("p2us")
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
    # labelling block k holds slider k: its field has the sign of limb k's IK discriminant wherever
    # it is defined, away from the locus itself (|disc| > 1e-6 m^2, far above both paths' rounding)
    assert np.isfinite(g.limb[:, 0]).all()  # block 0 carries the platform: always evaluable
    for k in range(3):
        ok = np.isfinite(g.limb[:, k]) & (np.abs(c.limb[:, k]) > 1e-6)
        assert ok.sum() > 300
        assert np.array_equal(g.limb[ok, k] >= 0, c.limb[ok, k] >= 0), k
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
    """On one grid the sign changes happen on the same edges wherever both fields are defined, so
    the counts are equal, not just close: type II and III everywhere, type I of limb 1 everywhere.
    Limbs 2 and 3 are measured from the platform, which hangs on limb 1 in the URDF tree: the
    generic path finds their loci only where limb 1 reaches (a subset)."""
    closed, generic = both
    kw = {"step": 0.05, "limits": "actuators"}
    c = singular_loci(closed, **kw)
    g = singular_loci(generic, **kw)
    cs, gs = c.summary(), g.summary()
    assert gs["type_II"] == cs["type_II"] and gs["type_III"] == cs["type_III"]
    assert cs["type_III"]["inside_workspace"] > 0  # the strokes-only workspace meets type III loci
    for limb in range(3):
        cl = (c.locus.kind == 1) & (c.locus.which == limb)
        gl = (g.locus.kind == 1) & (g.locus.which == limb)
        if limb == 0:
            assert gl.sum() == cl.sum() and (gl & g.locus.inside).sum() == (cl & c.locus.inside).sum()
        else:
            assert 0 < gl.sum() <= cl.sum()
    # the type II points lie on the same edges: each generic point within one step of a closed one
    from scipy.spatial import cKDTree

    sel_c = c.locus.kind >= 2
    sel_g = g.locus.kind >= 2
    d, _ = cKDTree(c.locus.points[sel_c]).query(g.locus.points[sel_g])
    assert np.all(d <= kw["step"])


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
