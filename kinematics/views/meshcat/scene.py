"""The meshcat scene: robots from their URDF visuals through Pinocchio's MeshcatVisualizer, their
kinematic skeletons, overlays (ellipsoids, meshes, point clouds, lines, an animation), the camera
and ground grid, and the output: a self-contained HTML page, a file, a screenshot, a notebook cell.

Two back ends behind one `Scene`:

* `Scene()` (default) records the meshcat commands in memory, exactly as meshcat's server keeps
  its scene tree, and `html()` writes them with the viewer's JavaScript inlined. No server
  process, no port, works in tests and notebooks (`Scene.notebook()`).
* `Scene(live=True)` starts meshcat's zmq/web server for a browser to connect to.

meshcat 0.3.2 faults worked around here: `Visualizer.close()` raises (we terminate the server
process ourselves, also at interpreter exit, since the zmq server otherwise outlives a killed
parent); Pinocchio's camera setters fail (we set the camera through `/Cameras/default` paths
directly); `get_image()` blocks without a connected browser (never called; screenshots are taken
by headless Chromium from the exported HTML).
"""

from __future__ import annotations

import atexit
import base64
import html as html_lib
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.errors import InvalidInputError
from kinematics.views.meshcat.materials import css_colour, hex_colour, points_material
from kinematics.views.meshcat.recording import Embedded, RecordingWindow, viewer_js
from kinematics.views.meshcat.skeletons import (
    SKELETON_STYLE,
    Skeleton,
    draw_skeleton,
    skeleton,
    skeleton_transforms,
)
from kinematics.views.meshcat.visuals import corners, visual_model

if TYPE_CHECKING:
    from kinematics.analyses.collisions import GridCounts

BACKGROUND = ((0.98, 0.98, 0.99), (0.78, 0.80, 0.84))
"""Sky gradient (top, bottom), RGB in 0..1: a light neutral grey, so that every part colour of the
built-in URDFs (orange, blue, red, dark grey) and every overlay colour map stands out; meshcat's
default sky is blue and swallows blue parts."""

FOV_DEG = 75.0
"""meshcat 0.3.2's default camera: vertical field of view [deg]."""

GRID_SQUARES = (1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01)
"""Side of the ground grid's squares [m], the largest that fits (see `Scene.camera`)."""


class Scene:
    """A meshcat scene with the toolkit's robots and overlays.

    Args:
        live: start meshcat's server (print `url`, keep the process alive while viewing);
            default records in memory for `html()` / `export()`.
        skeleton: draw every robot's kinematic skeleton, not only those whose visuals are missing.
    """

    def __init__(self, live: bool = False, skeleton: bool = False) -> None:
        import meshcat

        self.live = live
        self.skeleton = skeleton
        """Draw every robot's kinematic skeleton (`add_skeleton`) over its visuals; without it the
        skeleton is drawn only for a robot with visuals missing or none at all."""
        self._proc = None
        if live:
            import contextlib
            import io

            with contextlib.redirect_stdout(io.StringIO()):  # meshcat prints its URL on stdout
                self.vis = meshcat.Visualizer()
            self._proc = self.vis.window.server_proc
            atexit.register(self.close)
        else:
            self._window = RecordingWindow()
            self.vis = meshcat.Visualizer(window=self._window)
        self.robots: dict[str, Any] = {}
        self.configurations: dict[str, np.ndarray] = {}
        self.skeletons: dict[str, Skeleton] = {}
        """Robot name -> the skeleton drawn for it (`add_skeleton`)."""
        self.skipped: list[str] = []
        """Visuals not drawn (missing mesh files), one line each."""
        self.warnings: list[str] = []
        """What the reader must know about the picture (a singular pose, skipped meshes)."""
        self.collision_counts: GridCounts | None = None
        """The counts of the collision view's grid (`collision_views.colliding_overlay`), or None
        where no collision overlay was drawn."""
        self.legend: list[tuple[str, str]] = []
        """(label, CSS background: a colour, or a colour map's gradient) for every coloured overlay;
        a colour map's label starts with its range "lo → hi"."""
        self.camera_pose: tuple[np.ndarray, np.ndarray, float, float] | None = None
        """(position, target, ground height, grid extent) of the last `camera()` call [m]."""
        self.grid_square: float | None = None
        """Side of the grid's squares [m] (set by `camera()`)."""
        self._extent: list[np.ndarray] = []
        for key, rgb in zip(("top_color", "bottom_color"), BACKGROUND, strict=True):
            self.vis["/Background"].set_property(key, list(rgb))

    # -- lifecycle ----------------------------------------------------------------------------
    @property
    def url(self) -> str | None:
        return self.vis.url() if self.live else None

    def close(self) -> None:
        """End the meshcat server process, if any (meshcat's own close() raises in 0.3.2)."""
        proc, self._proc = self._proc, None
        if proc is not None and proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(5)
            except Exception:  # noqa: BLE001 - it must not survive us
                proc.kill()

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- camera ---------------------------------------------------------------------------------
    def camera(self, position: Sequence[float], target: Sequence[float] = (0.0, 0.0, 0.0),
               ground: float | None = None, extent: float | None = None) -> None:
        """Look at `target` from `position` (world z up) [m], over a ground grid at height
        `ground` (default: the target's) reaching `extent` [m] around the target (default: as far
        as it stays in front of the camera).

        meshcat 0.3.2's orbit controls always look at the viewer's origin (Pinocchio's camera
        setters fail, and the camera node cannot be given a target), so the scene is moved
        instead: the `/meshcat` root, the ground and the axes shift by -target, and the camera
        sits at position - target. The camera node is y-up: a world vector (x, y, z) is (x, z, -y)
        there. meshcat's own grid (20 m) is hidden: software WebGL (SwiftShader) drops the lines
        that cross the camera's plane, which left only its far edge on screen; ours has lines at
        multiples of the largest of GRID_SQUARES that gives it at least 5 squares each way.
        """
        import meshcat.geometry as mg
        import meshcat.transformations as tf

        t = np.asarray(target, dtype=float)
        p = np.asarray(position, dtype=float) - t
        z0 = t[2] if ground is None else float(ground)
        reach = 0.8 * max(float(np.hypot(p[0], p[1])), 1e-3)  # farther, the grid reaches behind the camera
        half = min(reach, extent) if extent else reach
        square = next((a for a in GRID_SQUARES if 5 * a <= half), GRID_SQUARES[-1])
        ticks = np.arange(-np.floor(half / square), np.floor(half / square) + 1) * square
        x, y = ticks + round(t[0] / square) * square, ticks + round(t[1] / square) * square
        segments = [((a, y[0]), (a, y[-1])) for a in x] + [((x[0], b), (x[-1], b)) for b in y]
        pts = np.array([(*q, z0) for seg in segments for q in seg]) - t
        self.vis["/Grid"].set_property("visible", False)
        self.vis["/Ground"].set_object(mg.LineSegments(mg.PointsGeometry(pts.T.astype(np.float32)),
                                                       mg.LineBasicMaterial(color=0x8C8C96)))
        self.vis["/meshcat"].set_transform(tf.translation_matrix(-t))
        self.vis["/Axes"].set_transform(tf.translation_matrix(-t) @ tf.scale_matrix(2 * square))  # 1 square long
        self.vis["/Cameras/default"].set_transform(np.eye(4))
        self.vis["/Cameras/default/rotated/<object>"].set_property("position", [float(p[0]), float(p[2]), float(-p[1])])
        self.camera_pose = (np.asarray(position, dtype=float), t, z0, half)
        self.grid_square = square

    def fit_camera(self, direction: Sequence[float] = (1.0, -1.4, 0.9), fill: float = 0.85,
                   aspect: float = 4 / 3) -> None:
        """Frame everything drawn so far: look along -direction at the centre of its bounding box,
        from the nearest distance at which every point lies within `fill` of the half-angles of
        a view `aspect` wide per unit height; the grid goes under the lowest point.

        A point at offset P from the target, seen from distance d along the unit vector u, is at
        tan(angle) = |P . axis| / (d - P . u) off the view's axis, so d >= P . u + |P . axis| /
        (fill tan(half-angle)) for both screen axes."""
        pts = self.extent
        if not len(pts):
            self.camera((3.0, 0.0, 1.0))  # meshcat's default view
            return
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = (lo + hi) / 2
        u = np.asarray(direction, dtype=float)
        u /= np.linalg.norm(u)
        right = np.cross(u, [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, u)
        P = pts - centre
        tan_v = fill * np.tan(np.radians(FOV_DEG) / 2)
        need = np.maximum(np.abs(P @ up) / tan_v, np.abs(P @ right) / (aspect * tan_v))
        distance = max(float(np.max(P @ u + need)), 0.1)
        footprint = float(np.max(hi[:2] - lo[:2])) / 2
        self.camera(centre + distance * u, centre, float(lo[2]), 1.3 * footprint + 0.05)

    @property
    def extent(self) -> np.ndarray:
        """(K, 3) every point [m, world] the camera frames so far (robots and overlays)."""
        return np.vstack(self._extent) if self._extent else np.zeros((0, 3))

    def _include(self, points: np.ndarray) -> None:
        """Points [m, world] the camera must frame."""
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        P = P[np.isfinite(P).all(axis=1)]
        if len(P):
            self._extent.append(P)

    # -- robots ----------------------------------------------------------------------------------
    def add_robot(self, robot: Any, q: np.ndarray, name: str | None = None,
                  colour: Sequence[float] | None = None) -> Any:
        """Draw `robot` (a `kinematics.model.robot.Robot`) at configuration q from its URDF visuals, in
        the URDF's material colours (or one `colour`). Visuals whose mesh file is missing are left
        out (listed in `skipped` and `warnings`); the primitives that exist are drawn, and so is the
        robot's kinematic skeleton (`add_skeleton`), as for a URDF with no visuals at all or a
        scene made with `skeleton=True`."""
        import pinocchio as pin
        from pinocchio.visualize import MeshcatVisualizer

        name = name or robot.name
        visual, skipped = visual_model(robot)
        if skipped:
            self.skipped += skipped
            self.warnings.append(f"{name}: {len(skipped)} visual(s) not drawn, mesh file missing; "
                                 "its kinematic skeleton is drawn instead")
        elif not visual.ngeoms and not self.skeleton:
            self.warnings.append(f"{name}: the URDF has no visuals; its kinematic skeleton is drawn instead")
        if colour is not None:
            for g in visual.geometryObjects:
                g.meshColor = np.array([*colour[:3], 1.0])
                g.overrideMaterial = True
        viz = MeshcatVisualizer(robot.model, pin.GeometryModel(), visual)
        viz.initViewer(viewer=self.vis)
        viz.loadViewerModel(rootNodeName=name)
        qa = np.asarray(q, dtype=float)
        viz.display(qa)
        self.robots[name] = viz
        self.configurations[name] = qa.copy()
        self._include(corners(visual, viz.visual_data))
        if self.skeleton or skipped or not visual.ngeoms:
            self.add_skeleton(robot, qa, name)
        return viz

    def add_skeleton(self, robot: Any, q: np.ndarray, name: str | None = None) -> Skeleton:
        """Draw what the kinematics knows of `robot` at configuration q, under `<name>_skeleton`:
        each link as a thin rod from its joint's origin to its child joints' origins and to its
        loop-closure and end-effector frames (`links/`), each joint at its origin along its axis,
        a short cylinder if revolute, an arrow if prismatic (`joints/`), each closure frame as a
        ball (`closures/`, both frames of a pair the same colour: apart where a loop is open) and
        the end effector as a larger ball. Sizes are fractions of the model's length scale L
        (SKELETON_SIZE); every object's transform puts it exactly (float64) where Pinocchio has
        the joint or frame."""
        name = name or robot.name
        sk = skeleton(robot, q)
        draw_skeleton(self.vis[f"{name}_skeleton"], sk)
        self.skeletons[name] = sk
        self._include(sk.points())
        grounded = [label.startswith("world->") for label, _, _ in sk.segments]
        used = {"ground": any(grounded), "link": not all(grounded), "revolute": any(j.kind == "revolute" for j in sk.joints),
                "prismatic": any(j.kind == "prismatic" for j in sk.joints), "closure": bool(sk.closures),
                "end_effector": True}
        self.legend += [(f"skeleton: {label}", css_colour(rgb)) for key, (rgb, label) in SKELETON_STYLE.items() if used[key]]
        return sk

    def animate(self, name: str, qs: np.ndarray, fps: float = 30.0, trace: np.ndarray | None = None) -> None:
        """Animate robot `name` through configurations qs (one per frame); optional tool trace."""
        import meshcat.animation as ma

        viz = self.robots[name]
        anim = ma.Animation(default_framerate=fps)
        saved = viz.viewer
        try:
            for k, q in enumerate(np.asarray(qs, dtype=float)):
                with anim.at_frame(self.vis, k) as frame:
                    viz.viewer = frame
                    viz.display(q)
                    if name in self.skeletons:  # the skeleton moves with the robot
                        sk = skeleton(self.skeletons[name].robot, q)
                        for path, matrix in skeleton_transforms(sk).items():
                            frame[f"{name}_skeleton/{path}"].set_transform(matrix)
        finally:
            viz.viewer = saved
        if trace is not None:
            self.add_line(trace, f"overlays/{name}_trace", (0.1, 0.6, 0.2), "tool path")
        self.vis.set_animation(anim, play=True, repetitions=1)

    # -- overlays ------------------------------------------------------------------------------
    def add_ellipsoid(self, centre: Sequence[float] | np.ndarray, radii: Sequence[float] | np.ndarray,
                      directions: np.ndarray,
                      name: str = "overlays/ellipsoid", colour: Sequence[float] = (0.55, 0.2, 0.85),
                      opacity: float = 0.5, label: str = "velocity ellipsoid") -> None:
        """An ellipsoid with semi-axes radii[k] along directions[k] (unit rows) at `centre` [m].
        Two radii (a planar ellipse) are drawn in the plane of the two directions, 2 mm thick."""
        import meshcat.geometry as mg

        r = np.asarray(radii, dtype=float)
        D = np.asarray(directions, dtype=float)
        if D.shape[1] == 2:
            D = np.hstack([D, np.zeros((len(D), 1))])
        if len(r) == 2:
            r = np.append(r, 0.001)
            D = np.vstack([D, np.cross(D[0], D[1])])
        R = D.T
        if np.linalg.det(R) < 0:
            R[:, -1] *= -1
        # meshcat (three.js) cannot draw a zero radius: keep a visible sliver
        r = np.maximum(r, 1e-3)
        T = np.eye(4)
        T[:3, :3] = R
        T[:3, 3] = np.asarray(centre, dtype=float)[:3] if len(centre) >= 3 else [*centre, 0.0]
        self.vis[name].set_object(mg.Ellipsoid(r.tolist()), mg.MeshLambertMaterial(
            color=hex_colour(colour), opacity=opacity, transparent=opacity < 1))
        self.vis[name].set_transform(T)
        self._include(T[:3, 3] + np.array([[s * r[k] * R[:, k] for k in range(3)] for s in (-1, 1)]).reshape(-1, 3))
        self.legend.append((label, css_colour(colour)))

    def add_mesh(self, vertices: np.ndarray, faces: np.ndarray, name: str = "overlays/boundary",
                 colour: Sequence[float] = (0.2, 0.53, 0.8), opacity: float = 0.4,
                 label: str = "workspace boundary mesh") -> None:
        """A triangle mesh (vertices (V, 3) [m], faces (F, 3) indices), translucent, e.g. a
        workspace boundary from `kinematics.analyses.boundary_mesh`."""
        import meshcat.geometry as mg

        V = np.asarray(vertices, dtype=float)
        F = np.asarray(faces)
        if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
            raise InvalidInputError("mesh", f"expected (V, 3) vertices and (F, 3) faces, got {V.shape} and {F.shape}")
        if F.min() < 0 or F.max() >= len(V):
            raise InvalidInputError("mesh", f"face indices must lie in [0, {len(V)}), got {F.min()} .. {F.max()}")
        self.vis[name].set_object(mg.TriangularMeshGeometry(V.astype(np.float32), F.astype(np.uint32)),
                                  mg.MeshLambertMaterial(color=hex_colour(colour), opacity=opacity, transparent=opacity < 1))
        self._include(V)
        self.legend.append((label, css_colour(colour)))

    def add_points(self, points: np.ndarray, values: np.ndarray | None = None, name: str = "overlays/points",
                   size: float = 0.006, cmap: str = "viridis", colour: Sequence[float] = (0.1, 0.1, 0.1),
                   vrange: tuple[float, float] | None = None, label: str | None = None,
                   opacity: float = 1.0) -> None:
        """A point cloud [m], coloured by `values` through a matplotlib colour map (or one colour);
        `label` names it in the legend (after the colour bar's range, for `values`)."""
        import meshcat.geometry as mg

        P = np.asarray(points, dtype=float)
        if P.ndim != 2 or P.shape[1] not in (2, 3):
            raise InvalidInputError("points", f"expected (N, 2) or (N, 3), got {P.shape}")
        if P.shape[1] == 2:
            P = np.hstack([P, np.zeros((len(P), 1))])
        if values is None:
            C = np.tile(np.asarray(colour, dtype=float), (len(P), 1))
            entry = css_colour(colour)
        else:
            from matplotlib import colormaps

            v = np.asarray(values, dtype=float)
            lo, hi = vrange or (float(np.min(v)), float(np.max(v)))
            C = colormaps[cmap]((v - lo) / (hi - lo if hi > lo else 1.0))[:, :3]
            stops = ", ".join(css_colour(colormaps[cmap](x)) for x in np.linspace(0, 1, 9))
            entry = f"linear-gradient(to right, {stops})"
            label = f"{lo:.3g} \u2192 {hi:.3g}: {label or name}"
        self.vis[name].set_object(mg.Points(mg.PointsGeometry(P.T.astype(np.float32), C.T.astype(np.float32)),
                                            points_material(size, opacity)))
        self._include(P)
        self.legend.append((label or name, entry))

    def add_line(self, points: np.ndarray, name: str, colour: Sequence[float] = (0.1, 0.6, 0.2),
                 label: str | None = None) -> None:
        import meshcat.geometry as mg

        P = np.asarray(points, dtype=float)
        if P.shape[1] == 2:
            P = np.hstack([P, np.zeros((len(P), 1))])
        self.vis[name].set_object(mg.Line(mg.PointsGeometry(P.T.astype(np.float32)),
                                          mg.LineBasicMaterial(color=hex_colour(colour))))
        self._include(P)
        self.legend.append((label or name, css_colour(colour)))

    # -- output ------------------------------------------------------------------------------------
    def html(self) -> str:
        """A self-contained HTML page of the scene (viewer JavaScript and commands inlined), with
        the legend of its coloured overlays and its warnings in a box at the bottom left."""
        if self.live:
            return self.vis.static_html()
        cmds = "\n".join(
            "viewer.handle_command_bytearray(Uint8Array.from(atob(\"{}\"), c => c.charCodeAt(0)));".format(
                base64.b64encode(c).decode("ascii"))
            for c in self._window.commands()
        )
        return (
            "<!DOCTYPE html>\n<html><head><meta charset=utf-8><title>kinematics - meshcat</title>\n"
            "<style>body{margin:0} #meshcat-pane{width:100vw;height:100vh;overflow:hidden}"
            " #legend{position:absolute;left:8px;bottom:8px;max-width:45%;padding:6px 8px;"
            "font:12px sans-serif;background:rgba(255,255,255,0.85);border-radius:4px}"
            " #legend span.key{display:inline-block;width:60px;height:10px;margin-right:6px;"
            "border:1px solid #555;vertical-align:middle} #legend .warn{color:#b00020;font-weight:bold}"
            "</style></head>\n<body><div id=\"meshcat-pane\"></div>\n" + self.legend_html() + "<script>\n"
            + viewer_js() + "\n</script>\n<script>\n"
            "var viewer = new MeshCat.Viewer(document.getElementById(\"meshcat-pane\"));\n" + cmds
            + "\n</script></body></html>\n"
        )

    def legend_html(self) -> str:
        """The legend box: one row per coloured overlay, then the warnings ("" when neither)."""
        rows = [f'<div><span class="key" style="background:{css}"></span>{html_lib.escape(label)}</div>'
                for label, css in self.legend]
        if self.grid_square is not None:
            rows.append(f"<div>grid squares: {self.grid_square:g} m</div>")
        rows += [f'<div class="warn">\u26a0 {html_lib.escape(w)}</div>' for w in self.warnings]
        return f'<div id="legend">{"".join(rows)}</div>\n' if rows else ""

    def export(self, path: str | os.PathLike[str]) -> None:
        """Write `html()` to a file (atomically)."""
        from kinematics.files import write_atomic

        write_atomic(os.fspath(path), self.html(), "--export")

    def screenshot(self, path: str | os.PathLike[str], size: tuple[int, int] = (800, 600),
                   browser: str | None = None) -> None:
        """Render the exported page to a PNG [px] with headless Chromium (software WebGL).

        Raises:
            KinematicsError: no `chromium-headless-shell` / `chromium` on PATH.
        """
        import shutil
        import subprocess
        import tempfile

        exe = browser or shutil.which("chromium-headless-shell") or shutil.which("chromium")
        if exe is None:
            from kinematics.errors import KinematicsError

            raise KinematicsError("screenshots need chromium-headless-shell or chromium on PATH")
        with tempfile.TemporaryDirectory() as tmp:
            page = Path(tmp) / "scene.html"
            page.write_text(self.html(), encoding="utf-8")
            cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
                   "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-component-update",
                   "--disable-sync", "--no-first-run", f"--user-data-dir={tmp}/profile",
                   f"--window-size={size[0]},{size[1]}", "--virtual-time-budget=8000",
                   f"--screenshot={Path(path).resolve()}", page.as_uri()]
            subprocess.run(cmd, check=True, capture_output=True, timeout=120)

    def notebook(self, height: int = 420) -> Any:
        """The scene for a notebook cell: an iframe with the page inlined (its `_repr_html_`;
        IPython's `HTML` would warn that an iframe belongs in `IFrame`, which cannot inline a page)."""
        return Embedded(f'<iframe srcdoc="{html_lib.escape(self.html(), quote=True)}" '
                         f'style="width:100%;height:{height}px;border:none"></iframe>')

