"""Closed poses and constrained Jacobians of any closed-loop robot, for the reports of the `fk`,
`jacobian` and `info` commands.

`closed_pose(loop)` is the pose a command without `--q` refers to: `ClosedLoop.assembly` (the
sidecar's reference, or a pose `kinematics.generic.assembly` found from the neutral pose), polished
by Newton on the passive joints to the solver's tolerance; with actuator values it is
`ClosedLoop.solve` (continuation from that pose). Each says where it came from.

`constrained_jacobian(loop, q, frame, rows)` is `ClosedLoop.constrained_jacobian` (any frame, any
subset of the six twist rows, the type II test made on those rows only) with a refusal that says
more: so the translation rows of a frame on a rod that spins
freely about its own axis (Gepetto's legs put their first closure frame there) are answered, and
a refusal says which rows move with the actuators locked and which frames the actuators do hold.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from kinematics.errors import SingularConfigurationError
from kinematics.generic.closedloop import FREE_RTOL, ClosedLoop, free_ratio
from kinematics.model.robot import matrix

ROW_NAMES = ("x", "y", "z", "wx", "wy", "wz")
"""The six rows of a world-aligned twist [v; w]."""

SUGGESTED_FRAMES = 3
"""How many held frames a type II refusal names."""


class ClosedPose(NamedTuple):
    """A configuration with every loop closed.

    Attributes:
        q: Pinocchio configuration.
        values: one value per degree of freedom (model order) [rad or m].
        actuated: the actuated joints' values (the sidecar's order) [rad or m].
        residual: largest closure error at q [m, or rad for a 6D closure].
        description: which pose this is, for reports.
    """

    q: np.ndarray
    values: np.ndarray
    actuated: np.ndarray
    residual: float
    description: str


def closed_pose(loop: ClosedLoop, actuated: Sequence[float] | np.ndarray | None = None) -> ClosedPose:
    """The default closed pose (`actuated` None) or the one at given actuator values.

    Raises:
        AssemblyError: no closed pose was found for the default.
        ConvergenceError: the loops do not close at `actuated`, neither by continuation from the
            default pose nor with the actuators held (`ClosedLoop.solve`'s fallback, as mobility and
            show pose it): no assembly there, or none found.
    """
    robot = loop.robot
    if actuated is None:
        a = loop.assembly
        q, err, _ = loop.newton(a.q)  # the assembly closes to 1e-10; polish to the solver's 1e-12
        if err > a.residual:
            q, err = a.q, a.residual
        values = robot.values_from_configuration(q)
        return ClosedPose(q, values, values[loop.actuated_dofs], float(err), a.description)
    target = np.asarray(actuated, dtype=float).reshape(-1)
    sol = loop.solve(target, fallback=True)
    start = loop.assembly.description
    how = (f"closed with the actuators held, possibly in another assembly mode: the continuation from {start} "
           "got stuck" if sol.held else f"reached by continuation from {start}")
    where = f"the actuator values {np.round(target, 9).tolist()} ({how})"
    return ClosedPose(sol.q, sol.values, sol.values[loop.actuated_dofs], float(sol.residual), where)


def _frame_jacobian(loop: ClosedLoop, q: np.ndarray, fid: int) -> np.ndarray:
    """6 x nv world-aligned Jacobian of frame `fid` (after `loop.residual(q)` ran the kinematics)."""
    return matrix(pin.getFrameJacobian(loop.model, loop.data, fid, pin.LOCAL_WORLD_ALIGNED), loop.model.nv)


def held_frames(loop: ClosedLoop, q: np.ndarray, rows: Sequence[int] = range(6),
                limit: int = SUGGESTED_FRAMES) -> list[str]:
    """Link frames whose `rows` the actuators determine at q, the farthest from the base first
    (most joints between them and the base), one per body, at most `limit`; bodies with mass
    first (a Gepetto SPHERICAL or UJOINT substitution's crosses are massless and no one's tool)."""
    _, _, N = loop.passive_null(q)
    model = loop.model
    rows = list(rows)
    seen: set[int] = set()
    found: list[tuple[bool, int, int, str]] = []
    for fid, f in enumerate(model.frames):
        if f.type != pin.FrameType.BODY or f.parentJoint == 0 or f.parentJoint in seen:
            continue
        J = _frame_jacobian(loop, q, fid)
        if free_ratio(J[rows][:, loop.passive_v], N) <= FREE_RTOL:
            seen.add(f.parentJoint)
            massless = not model.inertias[f.parentJoint].mass > 0
            found.append((massless, -len(model.supports[f.parentJoint]), fid, f.name))
    return [name for *_, name in sorted(found)[:limit]]


def constrained_jacobian(loop: ClosedLoop, q: np.ndarray, frame: str | None = None,
                         rows: Sequence[int] = range(6)) -> np.ndarray:
    """len(rows) x n_actuated map from actuator rates to the rows of `frame`'s world-aligned twist
    [v; w] (default frame: the end effector) at a closed configuration q.

    With the tool frame and all six rows it is `ClosedLoop.constrained_jacobian(q)`: the passive
    rates are the minimum-norm ones that keep the loops closed, -K_p^+ K_a, which is right as long
    as the passive motions left with the actuators locked (null(K_p)) do not move these rows.

    Raises:
        SingularConfigurationError: they do (|J_p N| > FREE_RTOL |J_p| on these rows): a type II
            singularity, or a frame the actuators never hold; the message names the rows that
            move and frames that are held.
        UnknownFrameError: no such frame.
    """
    try:
        return loop.constrained_jacobian(q, frame, rows)
    except SingularConfigurationError:
        pass
    # say which part moves and which frames the actuators do hold (kinematics at q just ran)
    fid = loop.robot.frame_id(frame)
    name = loop.model.frames[fid].name
    rows = list(rows)
    _, _, N = loop.passive_null(q)
    Jp = _frame_jacobian(loop, q, fid)[:, loop.passive_v]
    ratio = free_ratio(Jp[rows], N)
    lin = [r for r in rows if r < 3]
    ang = [r for r in rows if r >= 3]
    moving = [part for part, rr in (("position", lin), ("orientation", ang)) if rr and free_ratio(Jp[rr], N) > FREE_RTOL]
    held = [part for part, rr in (("position", lin), ("orientation", ang)) if rr and part not in moving]
    hint = []
    if held == ["position"]:
        hint.append("its position is held (--task translation gives that Jacobian)")
    others = [f for f in held_frames(loop, q, rows) if f != name]
    if others:
        hint.append("frames the actuators hold here: " + ", ".join(others) + " (--frame)")
    raise SingularConfigurationError(
        f"constrained Jacobian of frame {name!r}",
        f"its {' and '.join(moving)} can move with the actuators locked ({N.shape[1]} passive freedom(s) "
        f"then; |J_p N| / |J_p| = {ratio:.2e} > {FREE_RTOL:g} on rows {', '.join(ROW_NAMES[r] for r in rows)}): "
        "a type II (direct-kinematic) singularity of this pose, or a frame the actuators do not hold at any "
        "pose (e.g. on a rod free to spin about its own axis)" + ("; " + "; ".join(hint) if hint else "")) from None
