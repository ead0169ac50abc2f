"""Regenerate the figures of docs/ from the toolkit itself: python docs/make_figures.py [NAME ...]

Each figure is a function below; with no argument, all are drawn into docs/figures/.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from kinematics.mechanisms.p2us import closed_form as par
from kinematics.mechanisms.p2us.urdf import read_params
from kinematics.model.robot import load_robot

OUT = Path(__file__).resolve().parent / "figures"


def p2us_conventions() -> plt.Figure:
    """Top view of the base and side view of limb 1 at a sample pose, with the conventions."""
    P = read_params(load_robot("p2us").urdf_path)
    p = np.array([0.05, 0.0, -0.45])
    res = par.ik(P, p)
    q = res.q[par.mode_index("---")]
    B = P.base_points + q[:, None] * P.w
    C = p + P.d * P.e
    fig, (top, side) = plt.subplots(1, 2, figsize=(11, 5))
    ring = np.linspace(0, 2 * np.pi, 200)
    top.plot(P.b * np.cos(ring), P.b * np.sin(ring), color="0.7", lw=1)
    for i in range(3):
        A = P.base_points[i]
        end = A + P.stroke[1] * P.w[i]
        top.plot([A[0], end[0]], [A[1], end[1]], color="0.3", lw=3, alpha=0.5)
        top.plot([B[i, 0], C[i, 0]], [B[i, 1], C[i, 1]], color="tab:blue", lw=2)
        top.annotate(f"A{i + 1}", A[:2], textcoords="offset points", xytext=(6, 6))
        top.arrow(*A[:2], *(0.08 * P.e[i, :2]), width=0.003, color="tab:green")
        top.arrow(*A[:2], *(0.08 * P.t[i, :2]), width=0.003, color="tab:purple")
        top.annotate(f"e{i + 1}", A[:2] + 0.09 * P.e[i, :2], color="tab:green")
        top.annotate(f"t{i + 1}", A[:2] + 0.09 * P.t[i, :2], color="tab:purple")
    top.plot(*C[:, :2].T, "o", color="tab:red")
    top.plot(*p[:2], "x", color="tab:red")
    top.set_title("top view: base radius b, limbs at alpha_i, rails inward")
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    # side view of limb 1 in its vertical plane (horizontal coordinate along e_1)
    e1 = P.e[0]
    h = lambda v: float(v @ e1)  # noqa: E731
    A1 = P.base_points[0]
    rail_end = A1 + P.stroke[1] * P.w[0]
    side.plot([h(A1), h(rail_end)], [A1[2], rail_end[2]], color="0.3", lw=4, alpha=0.5, label="rail (q = 0 .. 0.6 m)")
    side.plot([h(B[0]), h(C[0])], [B[0, 2], C[0, 2]], color="tab:blue", lw=2, label="rod (length L)")
    side.plot(h(B[0]), B[0, 2], "s", color="tab:orange", label=f"carriage B1 (q1 = {q[0]:.3f} m)")
    side.plot(h(C[0]), C[0, 2], "o", color="tab:red", label="platform joint C1 = p + d e1")
    side.axhline(0, color="0.8", lw=1)
    side.annotate("beta: rail below horizontal", (h(A1) - 0.30, -0.04))
    theta, _ = par.passive_angles(P, (C - B)[None] / P.L)
    side.annotate(f"theta1 = {np.degrees(theta[0, 0]):.1f} deg\n(below the inward\nhorizontal)",
                  (h(B[0]) - 0.05, B[0, 2] - 0.12))
    side.plot([h(B[0]), h(B[0]) - 0.12], [B[0, 2], B[0, 2]], ":", color="tab:blue")
    side.set_title("limb 1 in its vertical plane (horizontal axis: along e1)")
    side.set_xlabel("along e1 [m]")
    side.set_ylabel("z [m]")
    side.set_aspect("equal")
    side.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig


def _p2us_params():
    return read_params(load_robot("p2us").urdf_path)


def p2us_workspace() -> plt.Figure:
    """Slices and a 3D view of the joint-limited workspace with its singular loci."""
    from kinematics.analyses.singularities import singular_loci
    from kinematics.mechanisms.p2us.mechanism import P2US
    from kinematics.views import plots

    P = _p2us_params()
    return plots.p2us_workspace(P, "all", 0.01, singular=singular_loci(P2US(P), step=0.01, progress=False).locus)


def p2us_workspace_actuators() -> plt.Figure:
    """The same with the actuator strokes only (every working mode)."""
    from kinematics.views import plots

    return plots.p2us_workspace(_p2us_params(), "actuators", 0.01)


def p2us_singular_loci() -> plt.Figure:
    """Type I/II/III loci over the strokes-only grid, the joint-limited workspace's points marked."""
    from kinematics.analyses.singularities import singular_loci
    from kinematics.mechanisms.p2us.mechanism import P2US
    from kinematics.views import plots

    return plots.p2us_singular_loci(singular_loci(P2US(_p2us_params()), step=0.01, limits="actuators", progress=False))


def volume_convergence() -> plt.Figure:
    """Adaptive estimate and bounds per level against uniform grids (same estimator)."""
    from kinematics.analyses.cells import adaptive_volume
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms.p2us.mechanism import P2US, p2us_margin
    from kinematics.mechanisms.p2us.scan import bounding_box
    from kinematics.views import plots

    P = _p2us_params()
    ws = measure_workspace(P2US(P), step=0.02, rtol=1e-4, progress=False, engine="cells")
    lo, hi = bounding_box(P)
    uniform = [(h, adaptive_volume(p2us_margin(P), lo, hi, h, None, progress=False).estimate[-1])
               for h in (0.02, 0.01, 0.005)]
    return plots.volume_convergence(ws, uniform)


def volume_vs_theta_zero() -> plt.Figure:
    """Union volume (every limit) against the theta reference: how much the paper's number hinges
    on an angle convention it does not state."""
    from kinematics.analyses.workspace import measure_workspace
    from kinematics.mechanisms.p2us.mechanism import P2US
    from kinematics.mechanisms.p2us.scan import PAPER_VOLUME_M3

    P = _p2us_params()
    zeros = np.radians(np.arange(-60, 61, 10))
    vols = [measure_workspace(P2US(P.replace(theta_zero=float(z))), step=0.02, rtol=1e-2, progress=False,
                              max_points=20_000_000).total for z in zeros]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(np.degrees(zeros), vols, "o-", label="ours, every limit, union of modes")
    ax.axhline(PAPER_VOLUME_M3, color="tab:red", ls="--", label="paper B: 0.13397 m^3")
    ax.set_xlabel("theta reference: rod elevation at theta = 0 [deg]")
    ax.set_ylabel("volume [m^3]")
    ax.legend()
    return fig


def scara_workspace() -> plt.Figure:
    """SCARA: smallest radius over the joint grid and the plane, with the theta2 = 0 arc."""
    from kinematics.mechanisms.scara.closed_form import ScaraParams
    from kinematics.mechanisms.scara.joint_space import singular_set
    from kinematics.views import plots

    sp = ScaraParams.from_robot(load_robot("scara"))
    return plots.scara_workspace(sp, singular_set(sp))


def _guidance(number: int, virtual: bool) -> plt.Figure:
    from kinematics.guidance.controller import GuidanceParams
    from kinematics.guidance.simulation import EXPERIMENTS, run_experiment
    from kinematics.mechanisms.scara.closed_form import ScaraParams
    from kinematics.views import plots

    sp = ScaraParams.from_robot(load_robot("scara"))
    run = run_experiment(number, sp, GuidanceParams(virtual_impedance=virtual))
    return plots.guidance_run(run, plots.guidance_title(EXPERIMENTS[number], run))


def _view(make) -> Path:
    """A Meshcat view as `kinematics show` exports it, screenshot by headless Chromium (800 x 600,
    software WebGL): the picture a new user sees first."""
    from tempfile import mkdtemp

    png = Path(mkdtemp()) / "view.png"
    make().screenshot(png)
    return png


def view_scara():
    """`kinematics show scara --ellipsoid --workspace --singularities`."""
    from kinematics.views import meshcat as viz

    return _view(lambda: viz.scara_view(load_robot("scara"), ellipse=True, workspace=True, singularities=True))


def view_p2us():
    """`kinematics show p2us --ellipsoid`."""
    from kinematics.views import meshcat as viz

    return _view(lambda: viz.parallel_view(load_robot("p2us"), ellipsoid=True))


def view_p2us_workspace():
    """`kinematics show p2us --workspace --singularities --limits actuators`."""
    from kinematics.views import meshcat as viz

    return _view(lambda: viz.parallel_view(load_robot("p2us"), workspace=True, singularities=True, limits="actuators"))


def view_ur5():
    """`kinematics show ur5 --ellipsoid` (example-robot-data meshes, default pose)."""
    from kinematics.views import meshcat as viz

    return _view(lambda: viz.serial_view(load_robot("ur5"), ellipsoid=True))


FIGURES = {
    "p2us_conventions": p2us_conventions,
    "p2us_workspace": p2us_workspace,
    "p2us_workspace_actuators": p2us_workspace_actuators,
    "p2us_singular_loci": p2us_singular_loci,
    "volume_convergence": volume_convergence,
    "volume_vs_theta_zero": volume_vs_theta_zero,
    "scara_workspace": scara_workspace,
    "guidance_exp1": lambda: _guidance(1, True),
    "guidance_exp2": lambda: _guidance(2, True),
    "guidance_exp3": lambda: _guidance(3, True),
    "guidance_exp3_baseline": lambda: _guidance(3, False),
    "view_scara": view_scara,
    "view_p2us": view_p2us,
    "view_p2us_workspace": view_p2us_workspace,
    "view_ur5": view_ur5,
}


def main(names: list[str]) -> None:
    OUT.mkdir(exist_ok=True)
    for name in names or list(FIGURES):
        fig = FIGURES[name]()
        if isinstance(fig, Path):  # a screenshot, already a PNG
            fig.replace(OUT / f"{name}.png")
            fig.parent.rmdir()
        else:
            fig.savefig(OUT / f"{name}.png", dpi=90, bbox_inches="tight")
            plt.close(fig)
        print(f"wrote {OUT / (name + '.png')}")


if __name__ == "__main__":
    main(sys.argv[1:])
