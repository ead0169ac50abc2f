"""The closed-form families' exact columns (p2us and delta `exact` modules) give the same columns,
bit for bit, on one core (calls of fewer than PARALLEL_COLUMNS columns) as on every core."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.mechanisms import mechanism_of
from kinematics.mechanisms.three_limb.column_ends import PARALLEL_COLUMNS
from kinematics.model.robot import load_robot


@pytest.mark.parametrize("robot", ["p2us-results", "delta"])
def test_one_core_and_every_core_agree(robot, rng):
    mech = mechanism_of(load_robot(robot))
    margin = mech.margin(limits="all")
    lo, hi = mech.bounding_box("all")
    ax = int(np.argmin(hi - lo))
    oth = [k for k in range(3) if k != ax]
    base = lo[oth] + (hi[oth] - lo[oth]) * rng.random((2 * PARALLEL_COLUMNS, 2))
    every = margin.exact_columns(base, ax, lo[ax], hi[ax])
    step = PARALLEL_COLUMNS // 4
    one = [margin.exact_columns(base[k:k + step], ax, lo[ax], hi[ax]) for k in range(0, len(base), step)]
    assert (every[0][:, -1] > 0).mean() > 0.2  # the columns cross the workspace
    for a, parts in zip(every, zip(*one, strict=True), strict=True):
        assert np.array_equal(a, np.concatenate(parts), equal_nan=True)
