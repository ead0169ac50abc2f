"""Shared fixtures: loaded robots are cached per session (loading parses XML)."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.model import Robot, load_robot


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
    path.write_text(
        f"""<robot name="arm2r">
  <link name="base"/><link name="a"/><link name="b"/><link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="{-lim1!r}" upper="{lim1!r}" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="{l1!r} 0 0.02"/><axis xyz="0 0 1"/><limit lower="{-lim2!r}" upper="{lim2!r}" effort="1" velocity="1"/></joint>
  <joint name="t" type="fixed"><parent link="b"/><child link="tip"/><origin xyz="{l2!r} 0 0"/></joint>
</robot>
"""
    )
