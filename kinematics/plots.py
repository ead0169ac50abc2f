"""Matplotlib figures for workspaces, singular loci, volume convergence and guidance runs.

matplotlib is imported inside each function so that the rest of the toolkit never pays for it.
The figures use whatever backend is active (inline in Jupyter); the CLI calls `headless()` first.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

SINGULAR_STYLE = {1: ("tab:blue", "o", "type I"), 2: ("tab:red", "^", "type II"), 3: ("black", "s", "type III")}
"""Singularity type -> (colour, marker, label), shared by every plot and the Meshcat views."""
RADIUS_CMAP = "magma"
"""Colour map of the smallest manipulability radius (SCARA plots and views)."""
CONDITIONING_CMAP = "viridis"
"""Colour map of the 3-[P2(US)] conditioning min(iota_I, iota_II) and mode counts."""
SCARA_SINGULAR_COLOUR = "cyan"
"""The theta2 = 0 singular arc: stands out on magma and on the views' light background."""


def headless() -> None:
    """Switch matplotlib to the file-only Agg backend (for the CLI: no window, no display needed)."""
    import matplotlib

    matplotlib.use("Agg")


def _figure(ncols: int = 1, size: tuple[float, float] = (6.0, 5.0), projection: list[str | None] | None = None) -> Any:
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(size[0] * ncols, size[1]))
    axes = [fig.add_subplot(1, ncols, k + 1, projection=(projection or [None] * ncols)[k]) for k in range(ncols)]
    return fig, axes


def save(fig: Any, path: str | os.PathLike[str]) -> None:
    """Write the figure (format from the suffix) atomically and close it."""
    import matplotlib.pyplot as plt

    path = os.fspath(path)
    root, ext = os.path.splitext(path)
    tmp = f"{root}.tmp{os.getpid()}{ext}"
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    os.replace(tmp, path)
    plt.close(fig)


def p2us_workspace(params: Any, limits: str = "all", step: float = 0.01, slices_z: int = 3,
                   singular: Any = None) -> Any:
    """Horizontal slices of the union workspace (coloured by the number of valid working modes)
    and a 3D view of its sampled points, with type II / I singular points when given."""
    from .p2us_scan import bounding_box, scan

    lo, hi = bounding_box(params)
    axes = [np.arange(lo[k], hi[k] + step / 2, step) for k in range(3)]
    X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
    pts3 = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    margin = scan(params, pts3, limits).margin
    count = (margin >= 0).sum(axis=1).reshape(len(axes[0]), len(axes[1]), len(axes[2]))
    filled = np.flatnonzero(count.reshape(-1, len(axes[2])).any(axis=0))
    picks = np.linspace(0.2, 0.8, slices_z) * (len(filled) - 1)
    zs = axes[2][filled[picks.round().astype(int)]] if len(filled) else np.repeat(axes[2][:1], slices_z)
    fig, ax = _figure(slices_z + 1, (4.2, 4.0), [None] * slices_z + ["3d"])
    for a, z in zip(ax[:-1], zs, strict=True):
        k = int(np.argmin(np.abs(axes[2] - z)))
        im = a.pcolormesh(X, Y, np.ma.masked_equal(count[:, :, k], 0), vmin=0, vmax=8, cmap="viridis", shading="auto")
        a.set_title(f"z = {z:.3f} m")
        a.set_aspect("equal")
        a.set_xlabel("x [m]")
        a.set_ylabel("y [m]")
    fig.colorbar(im, ax=ax[:-1], shrink=0.8, label="working modes within limits")
    inside = pts3[(margin >= 0).any(axis=1)]
    sub = inside[:: max(1, len(inside) // 20000)]
    ax[-1].scatter(sub[:, 0], sub[:, 1], sub[:, 2], s=1, c=sub[:, 2], cmap="viridis", alpha=0.3)
    if singular is not None:
        # only the singular points in the workspace (type I: on its boundary); the full loci
        # fill the bounding box and are drawn by `p2us_singular_loci`
        for kind, colour in ((1, "tab:blue"), (2, "red"), (3, "black")):
            sel = (singular.kind == kind) & singular.inside
            pts = singular.points[sel]
            ax[-1].scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=4, c=colour,
                           label=f"type {'I' * kind if kind < 3 else 'III'}: {int(sel.sum())}")
        ax[-1].legend(loc="upper left", fontsize=7, title="singular points in/on the workspace", title_fontsize=7)
    ax[-1].set_title(f"workspace ({limits} limits)")
    ax[-1].set_xlabel("x [m]")
    ax[-1].set_ylabel("y [m]")
    ax[-1].set_zlabel("z [m]")
    return fig


def p2us_singular_loci(scan_result: Any) -> Any:
    """Type I / II / III locus points in 3D and projected on x-z, those in the workspace highlighted."""
    loc = scan_result.locus
    fig, ax = _figure(2, (5.5, 5.0), ["3d", None])
    styles = {1: ("tab:blue", "type I"), 2: ("tab:red", "type II"), 3: ("black", "type III")}
    for kind, (colour, label) in styles.items():
        sel = loc.kind == kind
        pts = loc.points[sel][:: max(1, int(sel.sum()) // 4000)]
        ax[0].scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=1, c=colour, alpha=0.4, label=label)
        ax[1].scatter(pts[:, 0], pts[:, 2], s=1, c=colour, alpha=0.3, label=label)
    inside = loc.points[loc.inside]
    if len(inside):
        ax[1].scatter(inside[:, 0], inside[:, 2], s=6, facecolors="none", edgecolors="orange",
                      label="in the workspace (closure)")
    ax[0].set_title(f"singular loci (step {scan_result.step:g} m)")
    ax[1].set_xlabel("x [m]")
    ax[1].set_ylabel("z [m]")
    ax[1].legend(markerscale=4, fontsize=7)
    return fig


def volume_convergence(workspace: Any, uniform: list[tuple[float, float]] | None = None) -> Any:
    """Estimate and bounds per refinement level against the finest step, and optional uniform-grid
    estimates (step, value) for comparison."""
    lv = workspace.result.levels
    fig, ax = _figure(1, (6.0, 4.2))
    a = ax[0]
    steps = [x.step for x in lv]
    a.plot(steps, [x.estimate[-1] for x in lv], "o-", label="adaptive estimate")
    a.fill_between(steps, [x.lower[-1] for x in lv], [x.upper[-1] for x in lv], alpha=0.2, label="bounds")
    if uniform:
        s, v = zip(*uniform, strict=True)
        a.plot(s, v, "s--", label="uniform grid")
    a.set_xscale("log")
    a.invert_xaxis()
    a.set_xlabel("cell size [m]")
    a.set_ylabel("m^2" if workspace.planar else "volume [m^3]")
    a.set_title(f"{workspace.robot}: convergence ({workspace.limits} limits)")
    a.legend()
    return fig


def scara_workspace(sp: Any, sing: dict[str, Any]) -> Any:
    """SCARA: the smallest manipulability radius over the joint grid, and the reachable area in the
    plane coloured by it, with the theta2 = 0 singular arc."""
    from .scara import fk

    fig, ax = _figure(2, (5.2, 4.6))
    t1, t2 = np.degrees(sing["theta1"]), np.degrees(sing["theta2"])
    im = ax[0].pcolormesh(t1, t2, sing["min_radius"].T, shading="auto", cmap="magma")
    fig.colorbar(im, ax=ax[0], label="smallest radius [m]")
    ax[0].set_xlabel("theta1 [deg]")
    ax[0].set_ylabel("theta2 [deg]")
    ax[0].axhline(0.0, color="cyan", lw=1, label="theta2 = 0 (singular)")
    ax[0].legend(fontsize=7)
    Q = np.stack(np.meshgrid(sing["theta1"], sing["theta2"], indexing="ij"), axis=-1)
    xy = fk(sp, Q)
    sc = ax[1].scatter(xy[..., 0].ravel(), xy[..., 1].ravel(), c=sing["min_radius"].ravel(), s=1, cmap="magma")
    fig.colorbar(sc, ax=ax[1], label="smallest radius [m]")
    pts = sing["singular_points"]
    if len(pts):
        ax[1].plot(pts[:, 0], pts[:, 1], "c.", ms=2, label="singular (theta2 = 0)")
        ax[1].legend(fontsize=7)
    ax[1].set_aspect("equal")
    ax[1].set_xlabel("x [m]")
    ax[1].set_ylabel("y [m]")
    return fig


def guidance_run(run: Any, title: str = "") -> Any:
    """Paper A's Figs. 14-30 in one sheet: force, position, velocity before/after saturation,
    radii with the threshold, K_v = B_v, joint angles and joint speeds against time."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(4, 2, figsize=(11, 10), sharex=True)
    t = run.t
    axes = "xyz"[: run.x.shape[1]]
    panels = [
        (ax[0, 0], run.force, "force [N]", axes),
        (ax[0, 1], run.x, "position [m]", axes),
        (ax[1, 0], run.v_raw, "velocity before saturation [m/s]", axes),
        (ax[1, 1], run.v, "velocity (saturated) [m/s]", axes),
        (ax[2, 0], run.radii, "ellipse radii [m]", [f"r{k + 1}" for k in range(run.radii.shape[1])]),
        (ax[3, 0], run.q, "joint angles [rad]", [f"q{k + 1}" for k in range(run.q.shape[1])]),
        (ax[3, 1], run.qdot, "joint speeds [rad/s]", [f"q{k + 1}" for k in range(run.q.shape[1])]),
    ]
    for a, data, label, names in panels:
        for k, name in enumerate(names):
            a.plot(t, data[:, k], label=name, lw=1)
        a.set_ylabel(label, fontsize=8)
        a.legend(fontsize=7, loc="best")
    for a in (ax[1, 0], ax[1, 1]):
        for s in (-1, 1):
            a.axhline(s * run.params.v_max, color="0.6", ls=":", lw=1)
    ax[2, 0].axhline(run.params.threshold, color="tab:red", ls="--", lw=1, label="threshold")
    ax[2, 1].plot(t, run.k_v, color="tab:purple")
    ax[2, 1].set_ylabel("K_v = B_v [N/m, N s/m]", fontsize=8)
    for a in ax[-1]:
        a.set_xlabel("t [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
