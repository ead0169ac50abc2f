"""The 3-[P2(US)] URDF, its generator/reader and the loop sidecar."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.errors import ModelFileError, UnknownFrameError, UnknownJointError
from kinematics.generic.closedloop import ClosedLoop
from kinematics.mechanisms.p2us.closed_form import P2USParams
from kinematics.model.robot import URDF_DIR, load_robot, parser_agreement


def test_builtin_urdf_is_the_default_design(p2us_params):
    # (the committed files are the generator's output: test_three_limb)
    assert p2us_params == P2USParams()


def test_table2_values_read_from_urdf(p2us_params):
    p = p2us_params
    assert (p.b, p.d, p.L) == (0.325, 0.028, 0.340)
    assert p.beta == math.radians(40)
    assert p.alpha == (0.0, math.radians(120), math.radians(240))
    assert p.stroke == (0.1, 0.6)
    assert p.theta_limits == (math.radians(-10), math.radians(100))
    assert p.phi_limits == (math.radians(-70), math.radians(70))


def test_structure(p2us):
    kinds = [d.kind for d in p2us.dofs]
    assert kinds.count("prismatic") == 3 and kinds.count("revolute") == 15
    assert p2us.tool_frame == "platform"
    assert p2us.loops.actuated == ("slider_1", "slider_2", "slider_3")
    assert len(p2us.loops.closures) == 5 and all(c.type == "point" for c in p2us.loops.closures)


def test_parsers_agree(p2us, rng):
    cl = ClosedLoop(p2us)
    for values in (None, p2us.values_from_configuration(cl.reference), rng.uniform(-0.5, 0.5, p2us.nv)):
        agree = parser_agreement(p2us, values)
        assert agree.frames >= 40
        assert agree.max_position_error <= 1e-12 and agree.max_rotation_error <= 1e-12


def test_reference_configuration_is_assembled(p2us):
    cl = ClosedLoop(p2us)
    e, K = cl.residual(cl.reference)
    assert np.abs(e).max() <= 1e-12 and K.shape == (15, 18)


def random_design(rng):
    """A random valid 3-[P2(US)] design (test_three_limb's round trips)."""
    return P2USParams(
        b=float(rng.uniform(0.2, 0.5)), d=float(rng.uniform(0.01, 0.08)), L=float(rng.uniform(0.25, 0.6)),
        beta=float(rng.uniform(0.3, 1.0)), alpha=tuple(float(a) for a in np.sort(rng.uniform(0, 6.2, 3))),
        stroke=(float(rng.uniform(0.0, 0.2)), float(rng.uniform(0.5, 0.9))),
        theta_limits=(float(rng.uniform(-0.5, 0.0)), float(rng.uniform(1.2, 2.0))),
        phi_limits=(float(rng.uniform(-1.4, -0.5)), float(rng.uniform(0.5, 1.4))),
        theta_zero=float(rng.uniform(-0.3, 0.3)), rod_spacing=float(rng.uniform(0.02, 0.1)),
    )


def _copy_with_sidecar(tmp_path, sidecar: str):
    urdf = tmp_path / "robot.urdf"
    urdf.write_text((URDF_DIR / "p2us.urdf").read_text())
    (tmp_path / "robot.loops.yaml").write_text(sidecar)
    return urdf


def test_sidecar_errors(tmp_path):
    good = (URDF_DIR / "p2us.loops.yaml").read_text()
    with pytest.raises(UnknownFrameError, match="tip_9_9"):
        load_robot(_copy_with_sidecar(tmp_path, good.replace("frame1: tip_2_1", "frame1: tip_9_9")))
    with pytest.raises(UnknownJointError, match="slider_7"):
        load_robot(_copy_with_sidecar(tmp_path, good.replace("slider_3]", "slider_7]")))
    with pytest.raises(ModelFileError, match="malformed YAML"):
        load_robot(_copy_with_sidecar(tmp_path, good + "\n  - {unclosed: [\n"))
    with pytest.raises(ModelFileError, match="missing key 'actuated'"):
        load_robot(_copy_with_sidecar(tmp_path, good.replace("actuated:", "actuators:")))
    with pytest.raises(ModelFileError, match="unknown type"):
        load_robot(_copy_with_sidecar(tmp_path, good.replace("type: point", "type: hinge", 1)))
    # these three were tracebacks (TypeError, UnicodeDecodeError; the sizes a ValueError when a
    # sweep or a synthesis with --collisions read them)
    with pytest.raises(ModelFileError, match="disabled: expected a list of"):
        load_robot(_copy_with_sidecar(tmp_path, good.replace("disabled: []", "disabled: 7")))
    urdf = _copy_with_sidecar(tmp_path, "")
    (tmp_path / "robot.loops.yaml").write_bytes(b"\xff\xfe")
    with pytest.raises(ModelFileError, match="not UTF-8 text"):
        load_robot(urdf)
    from kinematics.analyses.collisions import design_options

    robot = load_robot(_copy_with_sidecar(tmp_path, good.replace("rod_radius: 0.006", "rod_radius: thick")))
    with pytest.raises(ModelFileError, match="sizes: expected numbers"):
        design_options(robot, True, None)


def test_invalid_designs_rejected():
    from kinematics.errors import InvalidInputError

    for bad in ({"L": -1.0}, {"b": float("nan")}, {"stroke": (0.6, 0.1)}, {"phi_limits": (-2.0, 2.0)}):
        with pytest.raises(InvalidInputError):
            P2USParams().replace(**bad)
    # a valid change: that parameter changed, every other one kept
    results = P2USParams(b=0.478, L=0.4, theta_convention="rod-rail")
    assert results.replace(L=0.38, stroke=(0.2, 0.5)) == P2USParams(b=0.478, L=0.38, stroke=(0.2, 0.5),
                                                                    theta_convention="rod-rail")


@pytest.mark.parametrize(("change", "parameter"), [
    ({"alpha": (0.0, 0.0, 0.0)}, "alpha"),
    ({"alpha": (0.0, 2 * math.pi, 2.0)}, "alpha"),  # the same limb angle modulo 360 degrees
    ({"d": 1.0}, "d"),
    ({"d": 0.325}, "d"),  # d = b: every rail starts on the platform's circle
    ({"beta": math.radians(400)}, "beta"),
    ({"beta": -0.1}, "beta"),
])
def test_degenerate_designs_rejected(change, parameter):
    """Defect 7: degenerate designs raise InvalidDesignError carrying the parameter and value,
    from the parameters (so the generator, the reader and the sweep all refuse them)."""
    from kinematics.errors import InvalidDesignError

    with pytest.raises(InvalidDesignError) as info:
        P2USParams().replace(**change)
    assert info.value.parameter == parameter and "\n" not in str(info.value)
    assert P2USParams().replace(beta=math.pi / 2).beta == math.pi / 2  # vertical rails are a design


def test_degenerate_design_cli(tmp_path, capsys):
    from .test_cli import run

    for flags in (["--alpha", "0", "0", "0"], ["--d", "1"], ["--degrees", "--beta", "400"]):
        out = tmp_path / "x.urdf"
        code, stdout, err = run(capsys, "urdf", "p2us", *flags, "-o", str(out))
        assert code == 2 and stdout == "" and len(err.strip().splitlines()) == 1
        assert not out.exists() and not list(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["p2us", "p2us-results"])
def test_compiled_configurations_are_the_closed_forms(name, rng):
    """`configurations_at` (compiled, one pass per point) against the closed forms it replaces
    (`limb_ik` per mode, `passive_angles`, the tree's named values) at random points of the
    bounding box in every working mode: the same NaN pattern (a limb that cannot reach) and the
    same values to 1e-11 (the IK square root near a reach boundary amplifies the roundings of a
    differently ordered sum: measured <= 8e-13 rad)."""
    from kinematics.mechanisms import mechanism_of
    from kinematics.mechanisms.p2us.closed_form import limb_ik, passive_angles
    from kinematics.mechanisms.p2us.urdf import configurations_at, theta_centre
    from kinematics.mechanisms.three_limb import urdf as three_limb
    from kinematics.mechanisms.three_limb.closed_form import MODES

    robot = load_robot(name)
    mech = mechanism_of(robot)
    lo, hi = mech.bounding_box("all")
    pts = lo + (hi - lo) * rng.random((4000, 3))
    for mode in MODES:
        q, n = three_limb.mode_solutions(limb_ik, mech.params, pts, mode)
        theta, phi = passive_angles(mech.params, n)
        ref = three_limb.tree_arrays(robot.model, three_limb.tree_value_arrays(
            "slider", q, "u_theta", theta, phi, theta_centre(mech.params) - theta[:, 0]))
        got = configurations_at(mech.params, robot.model, pts, mode)
        assert 0.2 < np.isfinite(ref).all(axis=1).mean() < 0.9  # points in and out of reach
        assert np.array_equal(np.isnan(got), np.isnan(ref))
        assert np.nanmax(np.abs(got - ref)) < 1e-11
