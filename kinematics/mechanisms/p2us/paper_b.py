"""Paper B's printed numbers and where each built-in design's parameters come from.

Paper B: Mazare, Taghizadeh & Najafi, "Design and kinematics of a 3-[P2(US)] translational
parallel robot", *Modares Mech. Eng.* 16(7), 2016. The numbers below are transcribed from it (SI
units; Table 3 is printed in centimetres under a "mm" header, see docs/paper-b-reproduction.md).
The toolkit's own numbers are always computed from the URDF; this module only holds the paper's,
for the reports that print them side by side.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kinematics.mechanisms.p2us.scan import (
    PAPER_VOLUME_M3 as VOLUME_M3,  # Sec. 8: 0.13397 m^3 with eq. 30's limits
)

REPRODUCTION_PAGE = "docs/paper-b-reproduction.md"

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
    from kinematics.model.robot import BUILTIN, URDF_DIR

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
            (f"paper B: {c['paper_volume_m3']} m^3; ours ({c['compared']}, {c['limits']} limits): "
             f"{c['ours_m3']:.6g} m^3, {100 * c['relative_difference']:+.2f} % (see {c['page']})")]


# -- the paper's computed results, recomputed for a design -----------------------------------------
def table3(params: Any) -> dict[str, Any]:
    """Table 3: the working mode's IK at (10, 10, -55) cm beside the paper's IK and ADAMS values."""
    from kinematics.mechanisms.p2us.closed_form import ik, mode_index

    res = ik(params, TABLE3_POSITION_M)
    m = mode_index(WORKING_MODE)
    q = res.q[m]
    return {"position_m": TABLE3_POSITION_M, "mode": WORKING_MODE, "q_m": q, "within_limits": bool(res.within_limits[m]),
            "paper_ik_m": TABLE3_Q_IK_M, "paper_adams_m": TABLE3_Q_ADAMS_M,
            "rel_diff_ik": float(np.max(np.abs(q / TABLE3_Q_IK_M - 1))),
            "rel_diff_adams": float(np.max(np.abs(q / TABLE3_Q_ADAMS_M - 1))),
            "paper_ik_vs_adams": float(np.max(np.abs(TABLE3_Q_IK_M / TABLE3_Q_ADAMS_M - 1)))}


def fit_table3(params: Any) -> dict[str, float]:
    """Solve Table 3's three rod equations |v_i - q_i w_i| = L (the paper's IK values, working
    root) for (b - d, L, beta), the limb angles as in `params`; Newton from `params`' values."""
    from scipy.optimize import least_squares

    alpha = np.asarray(params.alpha)
    e = np.stack([np.cos(alpha), np.sin(alpha), np.zeros(3)], axis=-1)

    def residual(x: np.ndarray) -> np.ndarray:
        r, L, beta = x
        w = np.concatenate([-np.cos(beta) * e[:, :2], np.full((3, 1), -np.sin(beta))], axis=-1)
        v = TABLE3_POSITION_M - r * e
        return np.linalg.norm(v - TABLE3_Q_IK_M[:, None] * w, axis=-1) - L

    sol = least_squares(residual, [params.b - params.d, params.L, params.beta], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    r, L, beta = sol.x
    return {"b_minus_d_m": float(r), "L_m": float(L), "beta_deg": float(np.degrees(beta)),
            "residual_m": float(np.max(np.abs(sol.fun)))}


def fig6(params: Any) -> dict[str, Any]:
    """Fig. 6: the working mode's IK at (-0.2, -0.2, -0.4) m and its limits."""
    from kinematics.mechanisms.p2us.closed_form import ik, mode_index, violations

    res = ik(params, FIG6_POSITION_M)
    m = mode_index(WORKING_MODE)
    roots = [0 if c == "+" else 1 for c in WORKING_MODE]
    ok = bool(res.reachable[m])
    viol = violations(params, res.q[m], res.limbs.n[np.arange(3), roots]) if ok else ["does not assemble"]
    return {"position_m": FIG6_POSITION_M, "mode": WORKING_MODE, "q_m": res.q[m], "assembles": ok,
            "within_limits": bool(res.within_limits[m]), "violations": viol,
            "modes_assembled": int(res.reachable.sum())}


def fig8(params: Any, actuators: Sequence[float] = (0.1, 0.7, 0.0)) -> dict[str, Any]:
    """Fig. 8: FK of q (both assembly modes), the distance of each pose from the printed one, and
    the singularity measures and type of the nearer pose (cosine of each rod-rail angle)."""
    from kinematics.mechanisms.p2us.closed_form import SINGULARITY_TYPES, classify, fk, jacobians, limb_ik

    q = np.asarray(actuators, dtype=float)
    res = fk(params, q)
    out: dict[str, Any] = {"q_m": q, "printed_pose_m": FIG8_POSITION_M, "assembles": bool(res.exists)}
    # the printed pose's distance from each rail axis, against L (reach needs <= L)
    out["axis_distance_m"] = limb_ik(params, FIG8_POSITION_M).axis_distance
    if not res.exists:
        return out
    dist = np.linalg.norm(res.p - FIG8_POSITION_M, axis=-1)
    k = int(np.argmin(dist))
    p = res.p[k]
    jac = jacobians(params, p, q)
    n = jac.Jx / params.L
    out.update({"poses_m": res.p, "distance_m": dist, "nearest": k, "pose_m": p,
                "rod_rail_cosines": np.einsum("ij,ij->i", n, params.w),
                "iota_I": float(jac.iota_I), "iota_II": float(jac.iota_II),
                "type_at_tolerance": SINGULARITY_TYPES[int(classify(jac.iota_I, jac.iota_II))]})
    return out


def fig7_scan(params: Any, levels: np.ndarray = FIG7_LEVELS_M) -> dict[str, Any]:
    """Fig. 7: the Jacobian at every triple of `levels` (8^3 = 512), FK below the carriages' plane
    (the assembly the paper draws). Returns the triples sorted by iota_I (the near-type-I ones
    first) and the count with iota_I or iota_II below 1e-2."""
    import itertools

    from kinematics.mechanisms.p2us.closed_form import fk, jacobians

    q = np.array(list(itertools.product(levels, levels, levels)))
    res = fk(params, q)
    ok = res.exists
    p = res.p[ok, 0]
    jac = jacobians(params, p, q[ok])
    order = np.argsort(jac.iota_I)
    return {"triples": len(q), "assembled": int(ok.sum()), "q_m": q[ok][order], "p_m": p[order],
            "iota_I": jac.iota_I[order], "iota_II": jac.iota_II[order],
            "near_singular": int(np.sum((jac.iota_I < 1e-2) | (jac.iota_II < 1e-2)))}


def binding_limits(params: Any, mode: str = WORKING_MODE, n: int = 200_000, seed: int = 0) -> dict[str, Any]:
    """How much volume each passive limit removes from a mode's strokes-only workspace [m^3]:
    a seeded Monte Carlo through the NumPy closed forms (volume, standard error), so a report can
    say which limits bind and by how much. A limit that never binds in the sample reports 0."""
    from kinematics.mechanisms.p2us.closed_form import limb_ik, limb_limits, mode_index
    from kinematics.mechanisms.p2us.scan import bounding_box

    mode_index(mode)
    lo, hi = bounding_box(params)
    p = lo + (hi - lo) * np.random.default_rng(seed).random((n, 3))
    limbs = limb_ik(params, p)
    stroke_ok, theta_ok, phi_ok = limb_limits(params, limbs)  # once: `ik` would evaluate them again
    roots = [0 if c == "+" else 1 for c in mode]
    idx = np.arange(3)
    inside = np.all((limbs.reach[..., None] & stroke_ok)[:, idx, roots], axis=-1)  # strokes only
    box = float(np.prod(hi - lo))
    out: dict[str, Any] = {"mode": mode, "samples": n}
    for name, ok in (("theta", theta_ok), ("phi", phi_ok)):
        cut = inside & ~np.all(ok[:, idx, roots], axis=-1)
        f = float(cut.mean())
        out[name] = {"volume_m3": box * f, "standard_error_m3": box * float(np.sqrt(f * (1 - f) / n)),
                     "convention": params.theta_convention if name == "theta" else params.phi_convention}
    return out


def reference_report(params: Any, robot_name: str, urdf_path: str | os.PathLike[str], limits: str,
                     per_mode: dict[str, float], union: float) -> dict[str, Any]:
    """The workspace-volume report's paper-B keys: `design` (the built-in name or the URDF path),
    `binding_limits` (the volume each passive limit removes from the working mode) and, for the
    built-ins, `paper_b` (paper B's volume beside ours, relative difference, the reproduction page,
    a note on why they differ), `paper_volume_m3` and `ratio_to_paper` (working mode over paper).

    Args:
        per_mode: measured volume [m^3] of each working mode; union: their union's [m^3].
    """
    c = volume_comparison(robot_name, urdf_path, limits, per_mode, union)
    out: dict[str, Any] = {"design": c.pop("design"), "binding_limits": binding_limits(params)}
    if c:
        c["note"] = volume_note(out["design"], limits)
        out.update(paper_b=c, paper_volume_m3=c["paper_volume_m3"], ratio_to_paper=c["ours_m3"] / c["paper_volume_m3"])
    return out


def reference_lines(report: dict[str, Any]) -> list[str]:
    """Human lines of `reference_report`."""
    c = report.get("paper_b", {"design": report["design"]})
    lines = comparison_lines({**c, "design": report["design"]})
    if "binding_limits" in report:
        b = report["binding_limits"]
        lines.append(f"passive limits on mode {b['mode']} (Monte Carlo, {b['samples']:,} samples): " + "; ".join(
            f"{k} ({b[k]['convention']}) removes {b[k]['volume_m3']:.4f} +/- {b[k]['standard_error_m3']:.4f} m^3"
            for k in ("theta", "phi")))
    return lines + ([c["note"]] if "note" in c else [])


def volume_note(design: str, limits: str) -> str:
    """Why our volume differs from paper B's 0.13397 m^3, for a built-in design."""
    if design == "p2us-results":
        return ("Read as the rod-rail angle, eq. 30's theta range never binds in the working mode and removes "
                "every other mode; phi and the strokes shape it. The remaining difference is of the size of "
                "a coarse grid count's scatter (see docs/paper-b-reproduction.md).")
    common = ("Table 2's dimensions do not give paper B's computed results; the geometry that does is the "
              "built-in p2us-results (docs/paper-b-reproduction.md). Paper B defines neither the universal "
              "joints' zero references nor which working modes it counts. ")
    if limits == "all":
        return common + ("With our references (theta = 0: rod horizontal, pointing inward; phi = 0: rod in the "
                         "limb's vertical plane) only working mode '---' respects the theta range, so every mode "
                         "but '---' is empty and the union is that one mode. See docs/workspace.md.")
    return common + ("With the actuator strokes alone, every working mode has a workspace and their union is "
                     "close to the paper's figure; the passive-joint limits are what shrink ours. See "
                     "docs/workspace.md.")
