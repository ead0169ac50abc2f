"""Regenerate the figures of docs/ from the toolkit itself: python docs/make_figures.py [NAME ...]

Each figure is a function below; with no argument, all are drawn into docs/figures/.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from kinematics import parallel as par  # noqa: E402
from kinematics.model import load_robot  # noqa: E402
from kinematics.p2us_urdf import read_params  # noqa: E402

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
    side.annotate("beta: rail below horizontal", (h(A1) - 0.12, -0.05))
    theta, _ = par.passive_angles(P, (C - B)[None] / P.L)
    side.annotate(f"theta1 = {np.degrees(theta[0, 0]):.1f} deg\n(below the inward horizontal)",
                  (h(B[0]) - 0.05, B[0, 2] - 0.12))
    side.plot([h(B[0]), h(B[0]) - 0.12], [B[0, 2], B[0, 2]], ":", color="tab:blue")
    side.set_title("limb 1 in its vertical plane (horizontal axis: along e1)")
    side.set_xlabel("along e1 [m]")
    side.set_ylabel("z [m]")
    side.set_aspect("equal")
    side.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return fig


FIGURES = {"p2us_conventions": p2us_conventions}


def main(names: list[str]) -> None:
    OUT.mkdir(exist_ok=True)
    for name in names or list(FIGURES):
        fig = FIGURES[name]()
        fig.savefig(OUT / f"{name}.png", dpi=110)
        plt.close(fig)
        print(f"wrote {OUT / (name + '.png')}")


if __name__ == "__main__":
    main(sys.argv[1:])
