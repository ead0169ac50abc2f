"""Matplotlib figures for workspaces, singular loci, volume convergence and guidance runs.

matplotlib is imported inside each function so that the rest of the toolkit never pays for it.
The figures use whatever backend is active (inline in Jupyter); the CLI calls `headless()` first.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from kinematics.sizes import check_count, check_points, grid_points

SINGULAR_STYLE = {1: ("tab:blue", "o", "type I"), 2: ("tab:red", "^", "type II"), 3: ("black", "s", "type III")}
"""Singularity type -> (colour, marker, label), shared by every plot and the Meshcat views."""
RADIUS_CMAP = "magma"
"""Colour map of the smallest manipulability radius (SCARA plots and views)."""
CONDITIONING_CMAP = "viridis"
"""Colour map of the 3-[P2(US)] conditioning min(iota_I, iota_II) and mode counts."""
LIMITS_TEXT = {"all": "all limits", "actuators": "actuator limits only"}
"""How the `limits` choices read in titles."""
SCARA_SINGULAR_COLOUR = "cyan"
"""The theta2 = 0 singular arc: stands out on magma and on the views' light background."""


def headless() -> None:
    """Switch matplotlib to the file-only Agg backend (for the CLI: no window, no display needed)."""
    import matplotlib

    matplotlib.use("Agg")


def _figure(ncols: int = 1, size: tuple[float, float] = (6.0, 5.0), projection: list[str | None] | None = None) -> Any:
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(size[0] * ncols, size[1]), layout="constrained")
    axes = [fig.add_subplot(1, ncols, k + 1, projection=(projection or [None] * ncols)[k]) for k in range(ncols)]
    return fig, axes


def save(fig: Any, path: str | os.PathLike[str], option: str = "--plot") -> None:
    """Write the figure (format from the suffix, one of `files.OUTPUT_SUFFIXES["figure"]`)
    atomically (`files.write_atomic`) and close it; InvalidInputError naming `option` otherwise."""
    import matplotlib.pyplot as plt

    from kinematics.files import check_output, write_atomic

    try:
        check_output(os.fspath(path), option, "figure")  # matplotlib's own refusal is a ValueError
        write_atomic(os.fspath(path), lambda tmp: fig.savefig(tmp, dpi=110, bbox_inches="tight"), option)
    finally:
        plt.close(fig)


def _check_grid(lo: np.ndarray, hi: np.ndarray, step: float, slices_z: int = 1) -> None:
    """The sampled grid's step (a positive length, `analyses.cells.check_step`), its size (the
    points budget) and the number of slices (a whole number >= 1), before anything is sampled."""
    from kinematics.analyses.cells import check_step

    check_step(step)
    check_count("slices_z", slices_z, 1, " of slices")
    check_points("step", grid_points(lo, hi, step), hint="use a larger step")


def p2us_workspace(params: Any, limits: str = "all", step: float = 0.01, slices_z: int = 3,
                   singular: Any = None) -> Any:
    """`spatial_workspace` of the 3-[P2(US)] design `params`."""
    from kinematics.mechanisms.p2us.mechanism import P2US

    return spatial_workspace(P2US(params), limits, step, slices_z, singular)


def spatial_workspace(mech: Any, limits: str = "all", step: float = 0.01, slices_z: int = 3,
                      singular: Any = None, branch_margin: Any = None, what: str = "",
                      branches: Sequence[str] | None = None) -> Any:
    """Horizontal slices of a spatial mechanism's union workspace (coloured by the number of
    branches, e.g. working modes, within limits there) and a 3D view of its sampled points, with
    type II / I singular points when given. A planar task space (x, y) gets `planar_workspace`.
    `branch_margin` (points (N, d) -> (N, branches)): each branch's margin in place of the
    mechanism's (e.g. the collision-aware one), `what` its word in the titles ("collision-free");
    `branches`: the branches counted (default: every one)."""
    if mech.task_dim == 2:
        return planar_workspace(mech, limits, step / 2, singular, branch_margin, what, branches)
    lo, hi = mech.bounding_box(limits)
    _check_grid(lo, hi, step, slices_z)
    axes = [np.arange(lo[k], hi[k] + step / 2, step) for k in range(3)]
    X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
    pts3 = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    margin = _branch_margins(mech, limits, branch_margin, pts3, branches)
    nb = margin.shape[1]
    count = (margin >= 0).sum(axis=1).reshape(len(axes[0]), len(axes[1]), len(axes[2]))
    filled = np.flatnonzero(count.reshape(-1, len(axes[2])).any(axis=0))
    picks = np.linspace(0.2, 0.8, slices_z) * (len(filled) - 1)
    zs = axes[2][filled[picks.round().astype(int)]] if len(filled) else np.repeat(axes[2][:1], slices_z)
    fig, ax = _figure(slices_z + 1, (4.2, 4.0), [None] * slices_z + ["3d"])
    for a, z in zip(ax[:-1], zs, strict=True):
        im = _count_map(a, X, Y, count[:, :, int(np.argmin(np.abs(axes[2] - z)))], nb)
        a.set_title(f"z = {z:.3f} m")
    fig.colorbar(im, ax=ax[:-1], shrink=0.8, label=f"{_counted(mech, branches)} within limits{_also(what)}")
    inside = pts3[(margin >= 0).any(axis=1)]
    sub = inside[:: max(1, len(inside) // 20000)]
    # grey, and faint under singular points so that they show
    ax[-1].scatter(sub[:, 0], sub[:, 1], sub[:, 2], s=1, c="0.45", alpha=0.08 if singular is not None else 0.3)
    if singular is not None:
        # only the singular points in the workspace (type I: on its boundary); the full loci
        # fill the bounding box and are drawn by `p2us_singular_loci`
        _singular_scatter(ax[-1], singular.points, singular.kind, singular.inside, 3, size=2.0)
        ax[-1].legend(loc="upper left", bbox_to_anchor=(0.0, -0.08), fontsize=7, markerscale=2, ncols=2,
                      title="singular points in / on the workspace", title_fontsize=7)
    ax[-1].set_title(f"{what + ' ' if what else ''}workspace ({LIMITS_TEXT[limits]})")
    ax[-1].set_xlabel("x [m]")
    ax[-1].set_ylabel("y [m]")
    ax[-1].set_zlabel("z [m]")
    return fig


def planar_workspace(mech: Any, limits: str = "all", step: float = 0.005, singular: Any = None,
                     branch_margin: Any = None, what: str = "", branches: Sequence[str] | None = None) -> Any:
    """A planar mechanism's union workspace over its (x, y) bounding box, coloured by the number of
    branches (e.g. working modes) within limits, with the singular points in (type II / III) or on
    (type I) it when given; `branch_margin`, `what` and `branches` as `spatial_workspace`'s."""
    lo, hi = mech.bounding_box(limits)
    _check_grid(lo, hi, step)
    axes = [np.arange(lo[k], hi[k] + step / 2, step) for k in range(2)]
    X, Y = np.meshgrid(*axes, indexing="ij")
    margin = _branch_margins(mech, limits, branch_margin, np.stack([X.ravel(), Y.ravel()], axis=1), branches)
    count = (margin >= 0).sum(axis=1).reshape(X.shape)
    fig, ax = _figure(1, (6.0, 5.0))
    im = _count_map(ax[0], X, Y, count, margin.shape[1])
    fig.colorbar(im, ax=ax[0], shrink=0.8, label=f"{_counted(mech, branches)} within limits{_also(what)}")
    if singular is not None:
        _singular_scatter(ax[0], singular.points, singular.kind, singular.inside, 2, size=2.0, plane=(0, 1))
        ax[0].legend(loc="upper left", bbox_to_anchor=(0.0, -0.1), fontsize=7, markerscale=2, ncols=3,
                     title="singular points in / on the workspace", title_fontsize=7)
    ax[0].set_title(f"{what + ' ' if what else ''}workspace ({LIMITS_TEXT[limits]})")
    return fig


def _branch_margins(mech: Any, limits: str, branch_margin: Any, points: np.ndarray,
                    branches: Sequence[str] | None) -> np.ndarray:
    """(N, len(branches)): `branch_margin(points)`, or the mechanism's own margin's, branch columns
    (`branches`, default every one); (N, 1) the union's (the last column) for a mechanism without
    branches (a serial arm)."""
    cols = [mech.branches.index(b) for b in mech.check_branches(branches)] if branches else slice(len(mech.branches))
    m = np.asarray(branch_margin(points)) if branch_margin is not None else mech.margin(None, limits)(points)
    return m[:, cols] if mech.branches else m[:, -1:]


def _counted(mech: Any, branches: Sequence[str] | None) -> str:
    """What a count map counts: a mechanism's branches, or the chosen ones (an arm without
    branches: whether its tool reaches the point)."""
    if not mech.branches:
        return "tool reaches (1)"
    if not branches or len(branches) == len(mech.branches):
        return f"{mech.branch_kind}s"
    return f"{mech.branch_kind}s of {', '.join(branches)}"


def _also(what: str) -> str:
    return f" and {what}" if what else ""


def _xy_plane(ax: Any) -> None:
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def _count_map(ax: Any, X: np.ndarray, Y: np.ndarray, count: np.ndarray, branches: int) -> Any:
    """The number of branches within limits over an x-y grid (none: blank); returns the mesh."""
    im = ax.pcolormesh(X, Y, np.ma.masked_equal(count, 0), vmin=0, vmax=branches, cmap=CONDITIONING_CMAP,
                       shading="auto")
    _xy_plane(ax)
    return im


def _singular_scatter(ax: Any, points: np.ndarray, kind: np.ndarray, select: np.ndarray | None, dims: int,
                      cap: int = 4000, size: float = 1.0, plane: tuple[int, int] = (0, 2)) -> None:
    """Singular points by type (`SINGULAR_STYLE` colour and marker, count in the label), the most
    numerous type first so that the rarer ones stay on top; at most `cap` drawn per type, marker
    areas scaled by `size`; in 2D the coordinates `plane` (x-z by default)."""
    counts = {k: int(((kind == k) if select is None else (kind == k) & select).sum()) for k in SINGULAR_STYLE}
    for k in sorted(counts, key=lambda k: -counts[k]):
        colour, marker, label = SINGULAR_STYLE[k]
        sel = (kind == k) if select is None else (kind == k) & select
        pts = points[sel][:: max(1, counts[k] // cap)]
        xyz = (pts[:, 0], pts[:, 1], pts[:, 2]) if dims == 3 else (pts[:, plane[0]], pts[:, plane[1]])
        # type I covers the workspace's boundary: faint when numerous, so II / III inside show through
        faint = k == 1 and counts[k] > 1000
        ax.scatter(*xyz, s=size * (3 if k == 1 else 4), c=colour, marker=marker, alpha=0.3 if faint else 0.8,
                   linewidths=0, label=f"{label}: {counts[k]}")
    if dims == 3:
        ax.computed_zorder = False  # draw in call order: by depth, the boundary hides the interior


def p2us_singular_loci(scan_result: Any) -> Any:
    """Type I / II / III locus points in 3D and projected on x-z; the points in (type II / III) or
    on (type I) the workspace get a panel of their own, so the closure does not hide the loci. Loci
    of a planar task space (points (K, 2)) get the two x-y panels."""
    loc = scan_result.locus
    if loc.points.shape[1] == 2:
        fig, ax = _figure(2, (4.6, 4.4))
        _singular_scatter(ax[0], loc.points, loc.kind, None, 2, plane=(0, 1))
        _singular_scatter(ax[1], loc.points, loc.kind, loc.inside, 2, plane=(0, 1))
        ax[0].set_title(f"singular loci over the bounding box (step {scan_result.step:g} m)", fontsize=9)
        ax[1].set_title(f"in / on the workspace ({LIMITS_TEXT[scan_result.limits]})", fontsize=9)
        for a in ax:
            _xy_plane(a)
            a.legend(markerscale=3, fontsize=7, loc="lower left")
        return fig
    fig, ax = _figure(3, (4.6, 4.4), ["3d", None, None])
    _singular_scatter(ax[0], loc.points, loc.kind, None, 3)
    _singular_scatter(ax[1], loc.points, loc.kind, None, 2)
    _singular_scatter(ax[2], loc.points, loc.kind, loc.inside, 2)
    ax[0].set_title(f"singular loci over the bounding box (step {scan_result.step:g} m)", fontsize=9)
    ax[1].set_title("the same, side view (x-z)", fontsize=9)
    ax[2].set_title(f"in / on the workspace ({LIMITS_TEXT[scan_result.limits]})", fontsize=9)
    ax[0].set_xlabel("x [m]")
    ax[0].set_ylabel("y [m]")
    ax[0].set_zlabel("z [m]")
    for a in ax[1:]:
        a.set_xlabel("x [m]")
        a.set_ylabel("z [m]")
        a.set_aspect("equal")
        a.legend(markerscale=3, fontsize=7, loc="lower left")
    ax[2].sharex(ax[1])
    ax[2].sharey(ax[1])
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
    a.set_ylabel("area [m^2]" if workspace.planar else "volume [m^3]")
    a.set_title(f"{workspace.robot}: convergence ({LIMITS_TEXT.get(workspace.limits, workspace.limits)})")
    a.legend()
    return fig


def scara_workspace(sp: Any, sing: dict[str, Any]) -> Any:
    """SCARA: the smallest manipulability radius over the joint grid, and the reachable area in the
    plane coloured by it (one colour bar for both), with the theta2 = 0 singular arc."""
    from kinematics.mechanisms.scara.closed_form import fk

    fig, ax = _figure(2, (5.0, 4.6))
    t1, t2 = np.degrees(sing["theta1"]), np.degrees(sing["theta2"])
    r = sing["min_radius"]
    norm = {"vmin": float(np.min(r)), "vmax": float(np.max(r)), "cmap": RADIUS_CMAP}
    im = ax[0].pcolormesh(t1, t2, r.T, shading="auto", **norm)
    ax[0].axhline(0.0, color=SCARA_SINGULAR_COLOUR, lw=1.5, label="theta2 = 0 (singular)")
    ax[0].set_xlabel("theta1 [deg]")
    ax[0].set_ylabel("theta2 [deg]")
    ax[0].set_title("joint space", fontsize=10)
    ax[0].legend(fontsize=7, loc="upper right")
    Q = np.stack(np.meshgrid(sing["theta1"], sing["theta2"], indexing="ij"), axis=-1)
    xy = fk(sp, Q)
    ax[1].scatter(xy[..., 0].ravel(), xy[..., 1].ravel(), c=r.ravel(), s=1, **norm)
    pts = sing["singular_points"]
    if len(pts):
        ax[1].plot(pts[:, 0], pts[:, 1], ".", color=SCARA_SINGULAR_COLOUR, ms=2,
                   label=f"singular (theta2 = 0): {len(pts)} points")
        ax[1].legend(fontsize=7, loc="upper right")
    _xy_plane(ax[1])
    ax[1].set_title("task space (reachable points)", fontsize=10)
    fig.colorbar(im, ax=ax, shrink=0.85, label="smallest manipulability radius [m per rad/s]")
    return fig


def guidance_title(experiment: Any, run: Any) -> str:
    """A title for a run of a paper A experiment: what the experiment shows (with the virtual
    impedance), then what this run did, from its data."""
    s = run.summary()
    head = f"experiment {experiment.number}: {experiment.title}"
    if not s["virtual_impedance"]:
        head = f"experiment {experiment.number}, baseline WITHOUT virtual impedance (with it: {experiment.title})"
    outcome = "reached the singularity" if s["reached_singularity"] else "stayed clear of the singularity"
    return (f"{head}\nthis run: {outcome} (smallest radius {s['min_radius']:.3g} m), "
            f"peak speed {s['max_speed']:.3g} m/s")


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
    ax[2, 0].legend(fontsize=7, loc="best")
    ax[2, 1].plot(t, run.k_v, color="tab:purple")
    ax[2, 1].set_ylabel("K_v = B_v [N/m, N s/m]", fontsize=8)
    for a in ax[-1]:
        a.set_xlabel("t [s]")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


INVERSE_KAPPA_CMAP = "viridis"
"""Colour map of 1/kappa (0 singular, 1 isotropic) in conditioning maps and views."""


def conditioning_map(mech: Any, branch: str, limits: str = "all", step: float | None = None,
                     slices_z: int = 3) -> Any:
    """Conditioning map of a mechanism's branch (or "union": the best branch at each point): 1/kappa
    of the forward Jacobian over the plane (planar arms) or over `slices_z` horizontal slices through
    the workspace (spatial mechanisms), blank outside it (`analyses.dexterity.conditioning_grid`)."""
    from kinematics.analyses.dexterity import conditioning_grid

    check_count("slices_z", slices_z, 1, " of slices")
    axes, g = conditioning_grid(mech, branch, limits=limits, step=step)
    if len(axes) == 2:
        fig, ax = _figure(1, (6.0, 5.0))
        levels = [(ax[0], g, "")]
    else:
        filled = np.flatnonzero(np.isfinite(g).reshape(-1, g.shape[2]).any(axis=0))
        picks = np.linspace(0.2, 0.8, slices_z) * max(len(filled) - 1, 0)
        ks = filled[picks.round().astype(int)] if len(filled) else np.zeros(slices_z, int)
        fig, ax = _figure(slices_z, (4.2, 4.0))
        levels = [(a, g[:, :, k], f"z = {axes[2][k]:.3f} m") for a, k in zip(ax, ks, strict=True)]
    X, Y = np.meshgrid(axes[0], axes[1], indexing="ij")
    im = None
    for a, values, title in levels:
        im = a.pcolormesh(X, Y, np.ma.masked_invalid(values), vmin=0.0, vmax=1.0, cmap=INVERSE_KAPPA_CMAP,
                          shading="auto")
        a.set_title(title)
        _xy_plane(a)
    fig.colorbar(im, ax=ax, shrink=0.8, label="1/\u03ba of J (0 singular, 1 isotropic)")
    fig.suptitle(f"{mech.name}: conditioning, {mech.branch_kind} {branch}, {LIMITS_TEXT.get(limits, limits)}")
    return fig


def pareto_front(front: Any, reference: dict[str, Any] | None = None) -> Any:
    """The Pareto front of a dimensional synthesis (`analyses.synthesis.Synthesis`): usable-cube
    edge against GCI, coloured by footprint, with an optional reference design marked."""
    fig, ax = _figure(1, (6.5, 5.0))
    F = np.asarray([[r["cube_edge_m"], r["gci"], r["footprint_m"]] for r in front.rows], dtype=float)
    sc = ax[0].scatter(F[:, 0], F[:, 1], c=F[:, 2], cmap="plasma", s=36, edgecolors="k", linewidths=0.4)
    fig.colorbar(sc, ax=ax[0], label=f"footprint [m] ({front.footprint_text})")
    if reference is not None:
        ax[0].scatter([reference["cube_edge_m"]], [reference["gci"]], marker="*", s=220, c="red",
                      edgecolors="k", label=reference.get("label", "reference design"))
        ax[0].legend(loc="best")
    ax[0].set_xlabel(f"usable cube edge [m] (\u03ba \u2264 {front.kappa_max:g}, mode {front.branch})")
    ax[0].set_ylabel("GCI (mean 1/\u03ba)")
    ax[0].set_title(f"{front.family}: Pareto front, {len(front.rows)} designs "
                    f"({front.generations} generations x {front.population})")
    ax[0].grid(alpha=0.3)
    return fig
