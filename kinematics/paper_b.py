"""Paper B's printed numbers and where each built-in design's parameters come from.

Paper B: Mazare, Taghizadeh & Najafi, "Design and kinematics of a 3-[P2(US)] translational
parallel robot", *Modares Mech. Eng.* 16(7), 2016. The numbers below are transcribed from it (SI
units; Table 3 is printed in centimetres under a "mm" header, see docs/paper-b-reproduction.md).
The toolkit's own numbers are always computed from the URDF; this module only holds the paper's,
for the reports that print them side by side.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

REPRODUCTION_PAGE = "docs/paper-b-reproduction.md"

VOLUME_M3 = 0.13397
"""Sec. 8: the workspace volume with the limits of eq. 30 [m^3]."""

TABLE3_POSITION_M = np.array([0.10, 0.10, -0.55])
"""Table 3's platform position, (10, 10, -55) read in cm [m]."""

TABLE3_Q_IK_M = np.array([0.3935419, 0.2614763, 0.3663527])
"""Table 3, the paper's IK at that position (39.35419, 26.14763, 36.63527 cm) [m]."""

TABLE3_Q_ADAMS_M = np.array([0.3935422, 0.2614771, 0.3663531])
"""Table 3, the ADAMS model's actuator values (39.35422, 26.14771, 36.63531 cm) [m]."""

FIG6_POSITION_M = np.array([-0.2, -0.2, -0.4])
"""Fig. 6: the platform position of the drawn IK configuration [m]."""

FIG8_POSITION_M = np.array([-0.315, -0.140, -0.145])
"""Fig. 8: the singular pose shown [m] (printed to the millimetre)."""

FIG7_LEVELS_M = np.arange(8) * 0.1
"""Fig. 7's scan: 8 levels per actuator (8^3 = 512 Jacobians); 0:100:700 mm reproduces Fig. 8."""

WORKING_MODE = "---"
"""The paper's accepted root on every limb (the platform below the carriages), in our labels."""

_TABLE2 = "Table 2"
_EQ30 = "eq. 30 (limits)"
_COMMON = {
    "d": "Table 2 (platform radius; only b - d enters a translating platform's kinematics)",
    "beta": "Table 2 (rail angle)",
    "stroke": "eq. 30: 100 mm <= q <= 600 mm",
    "theta_limits": "eq. 30: -10 deg <= theta <= 100 deg",
    "phi_limits": "eq. 30: -70 deg <= phi <= 70 deg",
    "rod_spacing": "not in the paper: our choice (does not enter the platform's kinematics)",
    "phi_convention": "model choice: phi out of the plane normal to the tangential axis (zero not given)",
}
SOURCES: dict[str, dict[str, str]] = {
    "p2us": {
        **_COMMON,
        "b": f"{_TABLE2} (base radius)",
        "L": f"{_TABLE2} (rod length; Table 1's hardware list says 400 mm)",
        "alpha": f"{_TABLE2}: alpha_i = (i - 1) 120 deg",
        "theta_zero": "model choice: theta = 0 with the rod along the inward horizontal (zero not given)",
        "theta_convention": "model choice: theta = the rod's elevation below the inward horizontal",
    },
    "p2us-results": {
        **_COMMON,
        "b": "reconstruction: b - d = 450 mm solves Table 3 and Fig. 8 (d kept from Table 2)",
        "L": "Table 1 (400 mm rods); reconstruction: solving Table 3 gives L = 400.0 mm",
        "alpha": "eq. 24 (limb directions (+/-sin alpha, -/+cos alpha): -90, 30, 150 deg); fits Table 3",
        "theta_zero": "model choice: the u_theta joint's zero (does not affect the limit checks here)",
        "theta_convention": "reconstruction: theta = the rod-rail angle, the reading under which eq. 30 "
                            "gives the paper's volume",
    },
}
"""Built-in robot name -> parameter -> where its number comes from (table, equation, reconstruction)."""


def builtin_design(robot_name: str, urdf_path: str | os.PathLike[str]) -> str | None:
    """The built-in name ("p2us", "p2us-results") when `urdf_path` is that built-in's URDF, else None."""
    from .model import BUILTIN, URDF_DIR

    if robot_name in SOURCES and Path(urdf_path).resolve() == (URDF_DIR / BUILTIN[robot_name]).resolve():
        return robot_name
    return None


def parameter_sources(robot_name: str, urdf_path: str | os.PathLike[str]) -> dict[str, str]:
    """Parameter -> source for a built-in 3-[P2(US)] design; every parameter "your URDF" otherwise."""
    design = builtin_design(robot_name, urdf_path)
    if design is None:
        return {}
    return dict(SOURCES[design])


def volume_comparison(robot_name: str, urdf_path: str | os.PathLike[str], limits: str,
                      per_mode: dict[str, float], union: float, error: float | None = None) -> dict[str, Any]:
    """The workspace-volume report's paper line: which design, and for the built-ins paper B's
    0.13397 m^3 beside ours with the relative difference.

    Ours is the working mode's volume (`WORKING_MODE`, the paper's accepted root) when it was
    measured, else the union of the measured modes.
    """
    design = builtin_design(robot_name, urdf_path)
    out: dict[str, Any] = {"design": design or str(urdf_path)}
    if design is None:
        return out
    measured = WORKING_MODE in per_mode
    ours = per_mode[WORKING_MODE] if measured else union
    out.update({
        "paper_volume_m3": VOLUME_M3,
        "compared": f"working mode {WORKING_MODE}" if measured else "union of the measured modes",
        "ours_m3": ours,
        "relative_difference": ours / VOLUME_M3 - 1.0,
        "limits": limits,
        "page": REPRODUCTION_PAGE,
    })
    return out


def comparison_lines(c: dict[str, Any]) -> list[str]:
    """Human lines of `volume_comparison`."""
    if "paper_volume_m3" not in c:
        return [f"design: {c['design']} (not a built-in: no paper value to compare)"]
    what = "Table 2's published dimensions" if c["design"] == "p2us" else "the geometry behind paper B's results"
    return [f"design: {c['design']} ({what})",
            f"paper B: {c['paper_volume_m3']} m^3; ours ({c['compared']}, {c['limits']} limits): "
            f"{c['ours_m3']:.6g} m^3, {100 * c['relative_difference']:+.2f} % (see {c['page']})"]
