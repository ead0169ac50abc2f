"""The three mobility analyses at one configuration, with notes wherever they disagree."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.model.robot import Robot

from .grubler import GrublerCount, grubler
from .numeric import NumericMobility, numeric_mobility, regular_configuration
from .screws import ScrewAnalysis, screw_analysis


@dataclass(frozen=True)
class MobilityReport:
    """The three analyses at one configuration, and what they say about each other."""

    grubler: GrublerCount
    numeric: NumericMobility
    screw: ScrewAnalysis
    notes: tuple[str, ...] = field(default=())

    def as_dict(self) -> dict[str, Any]:
        return {"grubler": self.grubler.as_dict(), "numeric": self.numeric.as_dict(),
                "screw": self.screw.as_dict(), "notes": list(self.notes)}


def analyse(robot: Robot, q: np.ndarray) -> MobilityReport:
    """Grübler–Kutzbach, numeric and screw mobility at Pinocchio configuration q (nq,), with notes
    wherever they disagree (InvalidInputError unless q is nq finite values)."""
    q = robot.check_configuration(q)
    g = grubler(robot, q)
    n = numeric_mobility(robot, q)
    s = screw_analysis(robot, q)
    notes = []
    if g.mobility != n.mobility:
        notes.append(
            f"Grübler-Kutzbach gives {g.mobility} (lambda = {g.lam}) but the constraint Jacobian has rank {n.rank}, "
            f"so the joints have {n.mobility} freedoms: the formula assumes independent constraints, but "
            f"{n.constraints - n.rank} of the {n.constraints} loop equations are redundant here "
            "(special geometry: parallel axes, a planar sub-loop, or a singular pose)")
    if n.idle > 0:
        notes.append(f"{n.idle} of the {n.mobility} joint freedoms are idle: they move joints but not the platform "
                     "(e.g. a rod spinning about its axis between two spherical joints)")
    if n.serial:
        generic = regular_configuration(robot).generic_rank
        lost = generic - n.platform_freedoms
        if lost > 0:
            notes.append(f"singular configuration: the tool's Jacobian has rank {n.platform_freedoms} here, "
                         f"{generic} at a regular pose of this arm; the freedoms reported are this pose's")
        if n.redundant > 0:
            why = [f"{n.mobility - generic} by design"] if n.mobility > generic else []
            why += [f"{lost} from the singularity"] if lost > 0 else []
            notes.append(f"{n.redundant} of the {n.mobility} joint freedoms are redundant: they move the joints "
                         f"without moving the tool ({', '.join(why)})")
    if s.translations + s.rotations != n.platform_freedoms:
        notes.append(f"screw theory finds {s.translations + s.rotations} platform freedoms but the constrained "
                     f"Jacobian {n.platform_freedoms}: the limbs' wrench systems are not a complete description here "
                     "(a singular pose, or constraints that only act at second order)")
    if n.locked_platform_freedoms > 0 and n.locked_position_freedoms == 0 and robot.loops is not None:
        from kinematics.generic.closedloop import ClosedLoop
        from kinematics.mechanisms.closed_loop import held_frames

        held = held_frames(ClosedLoop(robot), q)
        notes.append(f"with the actuators locked the end effector {robot.loops.end_effector!r} keeps "
                     f"{n.locked_platform_freedoms} freedom(s), all turning it about its own origin (its position "
                     "is held): a frame on a body the actuators do not hold (e.g. a rod free to spin about its own "
                     "axis), or a singular configuration (type II / direct-kinematic)"
                     + (f"; frames the actuators hold here: {', '.join(held)}" if held else ""))
    elif n.locked_platform_freedoms > 0:
        notes.append(f"with the actuators locked the platform keeps {n.locked_platform_freedoms} freedom(s): "
                     "a singular configuration (type II / direct-kinematic)")
    if np.isfinite(n.gap) and n.gap < 1e3:
        notes.append(f"the constraint Jacobian's singular values have no clear gap at the rank cut "
                     f"({n.smallest_kept:.3g} kept vs {n.largest_dropped:.3g} dropped): near a singularity")
    return MobilityReport(g, n, s, tuple(notes))
