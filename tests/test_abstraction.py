"""One mechanism abstraction: analyses take a `Mechanism` (no family-specific name in their
public API), the CLI reaches a closed-form family only through the mechanism `mechanism_of`
returns (no family table of its own), and the single-pose reports behind ik/fk/jacobian agree
with the families' vectorised maps."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

import kinematics.analyses as analyses
from kinematics.mechanisms import mechanism_of
from kinematics.model import load_robot

ROOT = Path(__file__).resolve().parents[1]
FAMILY_WORDS = ("p2us", "scara", "delta", "paper")
FAMILY_PARAMS = ("P2USParams", "ScaraParams", "DeltaParams")
CLOSED_FORM_FAMILIES = {"p2us", "delta", "scara"}
BRANCH_KEYS = CLOSED_FORM_FAMILIES | {"serial", "closed-loop"}  # no command compares a family key either
# the commands that use a family's closed forms (single-pose reports, workspace reports, design
# tools): none may decide the family itself; they ask the mechanism for capabilities
POSE_COMMANDS = ("ik", "fk", "jacobian", "mobility", "info", "views", "parallel", "workspace", "design")
UNASSEMBLED = {"p2us": [2.0, 0.1, 0.1], "delta": [3.0, 0.0, 0.0]}  # actuators no assembly fits
TABLE_NAMES = {"Family", "FAMILIES", "families", "family_of", "require_family", "params_of"}


def _family_specific(name: str, obj: object) -> list[str]:
    found = [f"{name}: its name names a family"] if any(w in name.lower() for w in FAMILY_WORDS) else []
    if callable(obj):
        try:
            sig = inspect.signature(obj)
        except (TypeError, ValueError):
            return found
        for p in sig.parameters.values():
            if any(t in str(p.annotation) for t in FAMILY_PARAMS):
                found.append(f"{name}({p.name}: {p.annotation}): takes a family's parameters")
    return found


def test_the_family_check_sees_names_and_parameters():
    def p2us_volume(params: P2USParams) -> float:  # noqa: F821 - only its annotation is read
        return 0.0

    def volume(mech: Mechanism, sp: ScaraParams) -> float:  # noqa: F821
        return 0.0

    assert len(_family_specific("p2us_volume", p2us_volume)) == 2
    assert _family_specific("volume", volume) == ["volume(sp: ScaraParams): takes a family's parameters"]
    assert _family_specific("measure_workspace", analyses.measure_workspace) == []


def test_analyses_export_no_family_specific_name():
    assert len(analyses.__all__) >= 10  # the check below reads a real list
    found = [hit for name in analyses.__all__ for hit in _family_specific(name, getattr(analyses, name))]
    assert not found, "\n".join(found)


def _cli_findings(source: str, where: str, pose_command: bool) -> list[str]:
    """A family table defined in the CLI; in a pose command, an import of a closed-form family's
    subpackage or a comparison with a closed-form family's key."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ClassDef | ast.FunctionDef) and node.name in TABLE_NAMES:
            found.append(f"{where}:{node.lineno}: defines {node.name}")
        if isinstance(node, ast.Assign):
            found += [f"{where}:{node.lineno}: defines {t.id}" for t in node.targets
                      if isinstance(t, ast.Name) and t.id in TABLE_NAMES]
        if not pose_command:
            continue
        if isinstance(node, ast.ImportFrom) and node.module:
            parts = node.module.split(".")
            if parts[:2] == ["kinematics", "mechanisms"] and len(parts) > 2 and parts[2] in CLOSED_FORM_FAMILIES:
                found.append(f"{where}:{node.lineno}: imports {node.module}")
        if isinstance(node, ast.Compare | ast.Dict):
            consts = [c.value for c in ast.walk(node) if isinstance(c, ast.Constant)]
            found += [f"{where}:{node.lineno}: branches on family {c!r}" for c in consts if c in BRANCH_KEYS]
    return found


def test_the_cli_check_sees_tables_imports_and_branches():
    src = ("from kinematics.mechanisms.p2us.closed_form import ik\nclass Family: pass\nFAMILIES = {}\n"
           "if mech.family == 'delta': pass\nx = {'p2us': 1}\nif kind == 'scara': pass\n")
    assert len(_cli_findings(src, "s", True)) == 6
    assert len(_cli_findings(src, "s", False)) == 2  # tables are refused in every CLI module


def test_the_cli_decides_no_family_outside_mechanism_of():
    found = []
    for f in sorted((ROOT / "kinematics" / "cli").glob("*.py")):
        found += _cli_findings(f.read_text(), str(f.relative_to(ROOT)), f.stem in POSE_COMMANDS)
    assert not found, "\n".join(found)


# -- the single-pose reports against the vectorised maps ------------------------------------------
@pytest.fixture(scope="module", params=["p2us", "delta"])
def mech(request):
    return mechanism_of(load_robot(request.param))


@pytest.mark.parametrize("name", ["p2us", "delta", "scara"])
def test_pose_ik_violations_match_the_limit_flags(name):
    """A branch breaks no limit in words exactly where the vectorised IK (`Mechanism.ik`, its own
    limit flags) says it is within limits; the limbs' reasons are given exactly where no branch
    exists."""
    mech = mechanism_of(load_robot(name))
    rng = np.random.default_rng(7)
    lo, hi = mech.bounding_box()
    seen_both = [0, 0]
    for p in lo + (hi - lo) * rng.random((60, mech.task_dim)):
        rep = mech.pose_ik(p)
        ref = mech.ik(p[None])
        np.testing.assert_array_equal(rep.reachable, ref.reachable[0])
        for m in np.flatnonzero(rep.reachable):
            assert (not rep.violations[m]) == bool(ref.within_limits[0, m]), (p, mech.branches[m], rep.violations[m])
            seen_both[bool(rep.violations[m])] += 1
        assert bool(rep.reason) == (not rep.reachable.any())
    assert min(seen_both) > 0  # both outcomes were met


def test_pose_fk_assemblies_solve_back_to_the_actuators(mech):
    """Each assembly mode's platform position, fed to the IK, gives back the actuator values in
    some working mode (to 1e-9: both closed forms are exact up to rounding of O(1) quantities)."""
    p0, branch = mech.reference_pose()
    q = mech.pose_ik(p0).q[mech.branches.index(branch)]
    rep = mech.pose_fk(q)
    assert rep.exists and rep.reason is None and len(rep.violations) == len(mech.assembly_modes)
    for p in rep.p:
        back = mech.pose_ik(p).q
        assert np.nanmin(np.abs(back - q).max(axis=1)) < 1e-9
    far = mech.pose_fk(np.array(UNASSEMBLED[mech.family]))
    assert not far.exists and far.reason and "no assembly" in far.reason and far.violations == ()


def test_pose_fk_violations_match_the_ik_limit_flags(mech):
    """An assembly breaks no limit in words exactly where the vectorised IK at its platform
    position, in the working mode that gives back these actuators, is within limits."""
    rng = np.random.default_rng(11)
    lo, hi = mech.params.stroke if mech.family == "p2us" else mech.params.theta_limits
    seen_both = [0, 0]
    for q in lo + (hi - lo) * rng.random((40, 3)):
        rep = mech.pose_fk(q)
        for p, viol in zip(rep.p, rep.violations, strict=True):
            ref = mech.ik(p[None])
            match = np.all(np.abs(ref.q[0] - q) < 1e-9, axis=-1)
            assert match.any()
            assert (not viol) == bool((match & ref.within_limits[0]).any()), (q, p, viol)
            seen_both[bool(viol)] += 1
    assert min(seen_both) > 0  # both outcomes were met


def test_pose_jacobians_match_finite_differences_of_the_ik(mech):
    """J (qdot = J pdot) of the report against central differences of the IK in the same working
    mode: step 1e-6 m, truncation ~ h^2 |q'''| ~ 1e-12, rounding ~ 1e-16 / 1e-6 = 1e-10: 1e-7 holds."""
    p0, branch = mech.reference_pose()
    k = mech.branches.index(branch)
    q = mech.pose_ik(p0).q[k]
    jac = mech.pose_jacobians(p0, q)
    h = 1e-6
    fd = np.stack([(mech.pose_ik(p0 + h * e).q[k] - mech.pose_ik(p0 - h * e).q[k]) / (2 * h) for e in np.eye(3)],
                  axis=1)
    np.testing.assert_allclose(jac.J, fd, atol=1e-7 * max(1.0, float(np.abs(fd).max())))
    assert 0 < float(jac.iota_I) <= 1 and 0 < float(jac.iota_II) <= 1
