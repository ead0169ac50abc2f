"""Shared fixtures (loaded robots are cached per session: loading parses XML) and test helpers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinematics.model.robot import Robot, load_robot

GEPETTO = Path(__file__).resolve().parents[2] / "shared" / "models" / "gepetto"
"""Gepetto's parallel-robot models, in the shared folder beside the repository (CI has it)."""

# The commands of the command line, written out by hand from the README's quick tour and the pages of
# docs/design.md (usable-workspace, dexterity, synthesize, workspace-mesh), not read
# from the parser that the CLI tests check.
COMMANDS = ("info", "fk", "ik", "jacobian", "manipulability", "mobility", "workspace-volume", "singularities",
            "sweep", "usable-workspace", "dexterity", "synthesize", "workspace-mesh", "guide", "show", "urdf")


@pytest.fixture(scope="session")
def scara() -> Robot:
    return load_robot("scara")


@pytest.fixture(scope="session")
def ur5() -> Robot:
    return load_robot("ur5")


@pytest.fixture()
def rng() -> np.random.Generator:
    return np.random.default_rng(20161108)


def write_2r_urdf(path, l1: float, l2: float, lim1: float = 2.0, lim2: float = 2.5) -> None:
    """A tiny planar 2R arm with arbitrary link lengths (tests the URDF reader)."""
    from kinematics.model.urdf_xml import UrdfBuilder

    urdf = UrdfBuilder("arm2r", {})
    for name in ("base", "a", "b", "tip"):
        urdf.link(name)
    urdf.joint("j1", "revolute", "base", "a", xyz=(0, 0, 0.1), axis=(0, 0, 1), limit=(-lim1, lim1))
    urdf.joint("j2", "revolute", "a", "b", xyz=(l1, 0, 0.02), axis=(0, 0, 1), limit=(-lim2, lim2))
    urdf.joint("t", "fixed", "b", "tip", xyz=(l2, 0, 0))
    path.write_text(urdf.text("A planar 2R arm written by tests/conftest.py."))


@pytest.fixture(scope="session")
def p2us() -> Robot:
    return load_robot("p2us")


@pytest.fixture(scope="session")
def p2us_params(p2us):
    from kinematics.mechanisms.p2us.urdf import read_params

    return read_params(p2us.urdf_path)


def sample_actuators(params, n: int, rng: np.random.Generator) -> np.ndarray:
    """Actuator values within the strokes at which the robot assembles (rejection sampling)."""
    from kinematics.mechanisms.p2us.closed_form import fk

    out = []
    while sum(len(o) for o in out) < n:
        q = rng.uniform(params.stroke[0], params.stroke[1], (4 * n, 3))
        out.append(q[fk(params, q).exists])
    return np.concatenate(out)[:n]


def limited_poses(ik, params, lo, hi, n: int, rng: np.random.Generator, oversample: int):
    """Up to n platform positions [m], uniform in the box lo..hi, where working mode '---' is
    assembled within every limit, and their actuator values (`ik`: a family's closed-form IK)."""
    p = rng.uniform(lo, hi, (oversample * n, 3))
    res = ik(params, p)
    ok = res.within_limits[:, -1]
    return p[ok][:n], res.q[ok, -1][:n]
