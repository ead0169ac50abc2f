"""The Delta URDF + sidecar (generator, reader, built-in) and the generic engine against the
closed forms: Pinocchio's closed loop for FK and its constrained Jacobian, mobility."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.errors import ConvergenceError, SingularConfigurationError
from kinematics.generic.closedloop import ClosedLoop
from kinematics.mechanisms.delta import closed_form as dl
from kinematics.mechanisms.delta.urdf import joint_values_at, read_params, write
from kinematics.model.robot import load_robot, parser_agreement

from .conftest import limited_poses
from .test_delta import sample_actuators, type_two_pose


@pytest.fixture(scope="module")
def delta():
    return load_robot("delta")


@pytest.fixture(scope="module")
def loop(delta):
    return ClosedLoop(delta)


@pytest.fixture(scope="module")
def params(delta):
    return read_params(delta.urdf_path)


def test_default_design_read_from_urdf(params):
    assert (params.R, params.r, params.la, params.lb) == (0.20, 0.05, 0.30, 0.80)
    assert params.alpha == (0.0, math.radians(120), math.radians(240))
    assert params.theta_limits == (math.radians(-40), math.radians(90))
    assert params.cone == math.radians(45)


def test_structure(delta):
    kinds = [d.kind for d in delta.dofs]
    assert kinds.count("revolute") == 18 and delta.tool_frame == "platform"
    assert delta.loops.actuated == ("actuator_1", "actuator_2", "actuator_3")
    assert delta.loops.mechanism == dl.MECHANISM
    assert len(delta.loops.closures) == 5 and all(c.type == "point" for c in delta.loops.closures)


def test_parsers_agree(delta, loop, rng):
    for values in (None, delta.values_from_configuration(loop.reference), rng.uniform(-0.5, 0.5, delta.nv)):
        agree = parser_agreement(delta, values)
        assert agree.frames >= 40
        assert agree.max_position_error <= 1e-12 and agree.max_rotation_error <= 1e-12


def random_design(rng):
    """A random valid Delta design (test_three_limb's round trips)."""
    lo = float(rng.uniform(-1.0, 0.0))
    return dl.DeltaParams(
        R=float(rng.uniform(0.1, 0.3)), r=float(rng.uniform(0.02, 0.08)), la=float(rng.uniform(0.2, 0.4)),
        lb=float(rng.uniform(0.5, 1.0)), alpha=tuple(float(a) for a in np.sort(rng.uniform(0, 6.2, 3))),
        theta_limits=(lo, float(rng.uniform(1.0, 1.6))), cone=float(rng.uniform(0.5, 0.9)),
        elbow_socket=float(rng.uniform(1.3, 1.8)), platform_socket=float(rng.uniform(0.0, 0.5)),
        rod_spacing=float(rng.uniform(0.03, 0.1)),
    )


def test_constrained_jacobian_matches_closed_form(loop, params, rng):
    """Pinocchio's constrained Jacobian (platform twist per actuator rate) vs J^-1 = J_x^-1 J_q
    on at least 100 seeded poses away from singularities (iota > 1e-3), 1e-9 relative."""
    worst, count = 0.0, 0
    for q in sample_actuators(params, 110, rng):
        sol = loop.solve(q)
        jac = dl.jacobians(params, sol.pose.translation, q)
        if jac.iota_II < 1e-3 or jac.iota_I < 1e-3:
            continue
        G = loop.constrained_jacobian(sol.q)
        inv = dl.jacobian_inverse(params, sol.pose.translation, q)
        worst = max(worst, np.abs(G[:3] - inv).max() / np.abs(inv).max())
        assert np.abs(G[3:]).max() <= 1e-9  # no angular velocity
        count += 1
    assert count >= 100 and worst <= 1e-9


def workspace_poses(P, n, rng):
    """Platform positions inside the limited workspace (mode '---') and their actuator angles."""
    return limited_poses(dl.ik, P, [-0.3, -0.3, -1.0], [0.3, 0.3, -0.6], n, rng, 50)


def test_passive_joints_match_closed_form(loop, delta, params, rng):
    """Inside the workspace the solver's joints are the closed-form angles, and the closed-form
    joint values close every loop."""
    for p_expected, q in zip(*workspace_poses(params, 30, rng), strict=True):
        sol = loop.solve(q)
        assert np.linalg.norm(sol.pose.translation - p_expected) <= 1e-9
        values = dict(zip(delta.joint_names, sol.values, strict=True))
        closed = joint_values_at(params, p_expected, "---")
        for name, v in closed.items():
            assert abs(math.remainder(values[name] - v, 2 * math.pi)) <= 1e-9, name
        qc = delta.configuration([closed[n] for n in delta.joint_names])
        assert np.abs(loop.residual(qc)[0]).max() <= 1e-12


def test_type_two_in_the_generic_engine(loop, delta, params):
    p, q = type_two_pose(params)
    mode = "+++"  # theta = 120 deg: the elbow turned past the line to the platform joint
    values = joint_values_at(params, p, mode)
    assert abs(values["actuator_1"] - q[0]) < 1e-12
    qc = delta.configuration([values[n] for n in delta.joint_names])
    assert np.abs(loop.residual(qc)[0]).max() <= 1e-12
    with pytest.raises(SingularConfigurationError):
        loop.constrained_jacobian(qc)


def test_no_assembly_is_a_clear_error(tmp_path):
    """The default design assembles for every actuator triple (the sphere centres' circumradius
    is at most R + la - r = 0.45 m < lb); with 0.3 m forearms and raised arms it cannot (the
    centres' circumradius is 0.38 m), and the generic engine says so."""
    urdf, _ = write(dl.DeltaParams(lb=0.3), tmp_path / "short.urdf")
    q = np.radians([-40.0, -40.0, -40.0])
    assert not dl.fk(read_params(urdf), q).exists
    with pytest.raises(ConvergenceError, match="no assembly"):
        ClosedLoop(load_robot(urdf)).solve(q)


def test_mobility_three_translations(delta, loop):
    from kinematics.analyses.mobility import analyse

    rep = analyse(delta, loop.reference)
    assert rep.grubler.mobility == 3 and rep.numeric.mobility == 3 and rep.numeric.platform_freedoms == 3
    assert rep.screw.translations == 3 and rep.screw.rotations == 0
    assert rep.numeric.locked_platform_freedoms == 0 and rep.notes == ()
