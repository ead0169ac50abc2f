"""Meshcat views: robots from their URDF visuals through Pinocchio's MeshcatVisualizer, with
overlays (manipulability ellipse/ellipsoid, workspace point clouds coloured by a measure, singular
points, an animated guidance run), served live or exported as one self-contained HTML file.

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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinematics.errors import InvalidInputError

BACKGROUND = ((0.98, 0.98, 0.99), (0.78, 0.80, 0.84))
"""Sky gradient (top, bottom), RGB in 0..1: a light neutral grey, so that every part colour of the
built-in URDFs (orange, blue, red, dark grey) and every overlay colour map stands out; meshcat's
default sky is blue and swallows blue parts."""

FOV_DEG = 75.0
"""meshcat 0.3.2's default camera: vertical field of view [deg]."""

GRID_SQUARES = (1.0, 0.5, 0.2, 0.1, 0.05, 0.02, 0.01)
"""Side of the ground grid's squares [m], the largest that fits (see `Scene.camera`)."""


class _RecordingWindow:
    """A meshcat ViewerWindow that keeps the scene tree in memory instead of sending it."""

    web_url = None

    def __init__(self) -> None:
        from meshcat.servers.tree import SceneTree

        self.tree = SceneTree()

    def send(self, command: Any) -> None:
        import umsgpack
        from meshcat.servers.tree import SceneTree, find_node

        data = command.lower()
        packed = umsgpack.packb(data)
        kind = data["type"]
        path = [p for p in data.get("path", "").split("/") if p]
        if kind == "set_object":
            node = find_node(self.tree, path)
            node.object, node.properties = packed, []
        elif kind == "set_transform":
            find_node(self.tree, path).transform = packed
        elif kind == "set_property":
            find_node(self.tree, path).properties.append(packed)
        elif kind == "set_animation":
            find_node(self.tree, path).animation = packed
        elif kind == "delete":
            if path:
                parent = find_node(self.tree, path[:-1])
                if path[-1] in parent:
                    del parent[path[-1]]
            else:
                self.tree = SceneTree()

    def commands(self) -> list[bytes]:
        from meshcat.servers.tree import walk

        out: list[bytes] = []
        for node in walk(self.tree):
            out += [node.object] if node.object is not None else []
            out += list(node.properties)
            out += [node.transform] if node.transform is not None else []
            out += [node.animation] if node.animation is not None else []
        return out

    def close(self) -> None:
        pass


def _viewer_js() -> str:
    from meshcat.servers.zmqserver import VIEWER_ROOT

    with open(os.path.join(VIEWER_ROOT, "main.min.js"), encoding="utf-8") as f:
        return f.read()


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
            self._window = _RecordingWindow()
            self.vis = meshcat.Visualizer(window=self._window)
        self.robots: dict[str, Any] = {}
        self.configurations: dict[str, np.ndarray] = {}
        self.skeletons: dict[str, Skeleton] = {}
        """Robot name -> the skeleton drawn for it (`add_skeleton`)."""
        self.skipped: list[str] = []
        """Visuals not drawn (missing mesh files), one line each."""
        self.warnings: list[str] = []
        """What the reader must know about the picture (a singular pose, skipped meshes)."""
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
        if not self._extent:
            self.camera((3.0, 0.0, 1.0))  # meshcat's default view
            return
        pts = np.vstack(self._extent)
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
        self._include(_corners(visual, viz.visual_data))
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
        import meshcat.geometry as mg

        name = name or robot.name
        sk = skeleton(robot, q)
        L = sk.length
        root = self.vis[f"{name}_skeleton"]
        material = {key: mg.MeshLambertMaterial(color=_hex(rgb)) for key, (rgb, _) in SKELETON_STYLE.items()}
        for path, matrix in skeleton_transforms(sk).items():
            kind = path.split("/", 1)[0]
            node = root[path]
            if kind == "links":
                ground = path.split("_", 1)[1].startswith("world->")
                node.set_object(mg.Cylinder(1.0, SKELETON_SIZE["link"] * L), material["ground" if ground else "link"])
            elif kind == "joints" and sk.joint(path).kind == "revolute":
                node.set_object(mg.Cylinder(SKELETON_SIZE["joint_length"] * L, SKELETON_SIZE["joint_radius"] * L),
                                material["revolute"])
            elif kind == "joints":  # an arrow along +axis: shaft and head, in the joint's node
                shaft, head = SKELETON_SIZE["arrow_length"] * L, SKELETON_SIZE["arrow_head"] * L
                node["shaft"].set_object(mg.Cylinder(shaft, SKELETON_SIZE["joint_radius"] * L / 2), material["prismatic"])
                node["shaft"].set_transform(_translation(0.0, shaft / 2, 0.0))
                node["head"].set_object(mg.Cylinder(head, radiusTop=0.0, radiusBottom=SKELETON_SIZE["joint_radius"] * L),
                                        material["prismatic"])
                node["head"].set_transform(_translation(0.0, shaft + head / 2, 0.0))
            elif kind == "closures":
                node.set_object(mg.Sphere(SKELETON_SIZE["closure"] * L), material["closure"])
            else:
                node.set_object(mg.Sphere(SKELETON_SIZE["end_effector"] * L), material["end_effector"])
            node.set_transform(matrix)
        self.skeletons[name] = sk
        self._include(sk.points())
        grounded = [label.startswith("world->") for label, _, _ in sk.segments]
        used = {"ground": any(grounded), "link": not all(grounded), "revolute": any(j.kind == "revolute" for j in sk.joints),
                "prismatic": any(j.kind == "prismatic" for j in sk.joints), "closure": bool(sk.closures),
                "end_effector": True}
        self.legend += [(f"skeleton: {label}", _css(rgb)) for key, (rgb, label) in SKELETON_STYLE.items() if used[key]]
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
            color=_hex(colour), opacity=opacity, transparent=opacity < 1))
        self.vis[name].set_transform(T)
        self._include(T[:3, 3] + np.array([[s * r[k] * R[:, k] for k in range(3)] for s in (-1, 1)]).reshape(-1, 3))
        self.legend.append((label, _css(colour)))

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
                                  mg.MeshLambertMaterial(color=_hex(colour), opacity=opacity, transparent=opacity < 1))
        self._include(V)
        self.legend.append((label, _css(colour)))

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
            entry = _css(colour)
        else:
            from matplotlib import colormaps

            v = np.asarray(values, dtype=float)
            lo, hi = vrange or (float(np.min(v)), float(np.max(v)))
            C = colormaps[cmap]((v - lo) / (hi - lo if hi > lo else 1.0))[:, :3]
            stops = ", ".join(_css(colormaps[cmap](x)) for x in np.linspace(0, 1, 9))
            entry = f"linear-gradient(to right, {stops})"
            label = f"{lo:.3g} \u2192 {hi:.3g}: {label or name}"
        self.vis[name].set_object(mg.Points(mg.PointsGeometry(P.T.astype(np.float32), C.T.astype(np.float32)),
                                            _points_material(size, opacity)))
        self._include(P)
        self.legend.append((label or name, entry))

    def add_line(self, points: np.ndarray, name: str, colour: Sequence[float] = (0.1, 0.6, 0.2),
                 label: str | None = None) -> None:
        import meshcat.geometry as mg

        P = np.asarray(points, dtype=float)
        if P.shape[1] == 2:
            P = np.hstack([P, np.zeros((len(P), 1))])
        self.vis[name].set_object(mg.Line(mg.PointsGeometry(P.T.astype(np.float32)),
                                          mg.LineBasicMaterial(color=_hex(colour))))
        self._include(P)
        self.legend.append((label or name, _css(colour)))

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
            + _viewer_js() + "\n</script>\n<script>\n"
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
        return _Embedded(f'<iframe srcdoc="{html_lib.escape(self.html(), quote=True)}" '
                         f'style="width:100%;height:{height}px;border:none"></iframe>')


class _Embedded:
    def __init__(self, markup: str) -> None:
        self.markup = markup

    def _repr_html_(self) -> str:
        return self.markup

    def __repr__(self) -> str:
        return "<Meshcat scene: shown as HTML in Jupyter>"


def _points_material(size: float, opacity: float) -> Any:
    """meshcat's PointsMaterial, with the opacity 0.3.2's lacks."""
    import meshcat.geometry as mg

    material = mg.PointsMaterial(size=size)
    plain = material.lower
    material.lower = lambda data: {**plain(data), "opacity": opacity, "transparent": opacity < 1}
    return material


def visual_model(robot: Any) -> tuple[Any, list[str]]:
    """The robot's visual GeometryModel and a line per <visual> left out because its mesh file is
    missing (Pinocchio raises on the first one): the primitives and the meshes that exist stay."""
    import xml.etree.ElementTree as ET

    import pinocchio as pin

    path = Path(robot.urdf_path)
    dirs = list(robot.package_dirs)
    try:
        return pin.buildGeomFromUrdf(robot.model, str(path), pin.GeometryType.VISUAL, package_dirs=dirs or None), []
    except ValueError as exc:
        if "could not be found" not in str(exc):
            raise
    dirs += [d for d in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if d]
    root = ET.fromstring(path.read_text(encoding="utf-8"))
    skipped: list[str] = []
    for link in root.iter("link"):
        for vis in list(link.findall("visual")):
            for mesh in vis.iter("mesh"):
                name = mesh.get("filename", "")
                found = _mesh_file(name, path.parent, dirs)
                if found is None:
                    link.remove(vis)
                    skipped.append(f"link {link.get('name')}: {name}")
                    break
                mesh.set("filename", found)  # absolute: the string below has no directory
    return pin.buildGeomFromUrdfString(robot.model, ET.tostring(root, encoding="unicode"), pin.GeometryType.VISUAL,
                                       package_dirs=dirs or None), skipped


def _mesh_file(name: str, here: Path, package_dirs: list[str]) -> str | None:
    """Where a URDF mesh filename points, as Pinocchio resolves it (package:// in the package
    directories, file:// and absolute as given, relative to the URDF's folder), if it exists."""
    if name.startswith("package://"):
        candidates = [Path(d) / name.removeprefix("package://") for d in package_dirs]
    else:
        candidates = [here / name.removeprefix("file://")]  # an absolute name ignores `here`
    return next((str(c) for c in candidates if c.is_file()), None)


def _corners(geometry: Any, data: Any) -> np.ndarray:
    """World corners [m] of every visual's local bounding box, at the placements in `data`."""
    out = []
    signs = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
    for g, M in zip(geometry.geometryObjects, data.oMg, strict=True):
        g.geometry.computeLocalAABB()
        box = g.geometry.aabb_local
        lo, hi = np.asarray(box.min_), np.asarray(box.max_)  # meshes are loaded scaled
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            continue
        local = lo + signs * (hi - lo)
        out.append(local @ M.rotation.T + M.translation)
    return np.vstack(out) if out else np.zeros((0, 3))


def _css(rgb: Sequence[float]) -> str:
    return f"#{_hex(rgb):06x}"


def _hex(rgb: Sequence[float]) -> int:
    r, g, b = (round(255 * max(0.0, min(1.0, c))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


# -- skeletons ------------------------------------------------------------------------------------
SKELETON_SIZE = {
    "link": 0.005,  # rod radius
    "joint_length": 0.08,  # revolute cylinder, along the axis
    "joint_radius": 0.015,
    "arrow_length": 0.10,  # prismatic arrow's shaft
    "arrow_head": 0.04,
    "closure": 0.02,  # ball radius
    "end_effector": 0.03,
}
"""Skeleton sizes as fractions of the model's length scale L (`generic.serial.length_scale`, the
diagonal of the bounding box of its joints and frames): robot_delta (L = 0.11 m) gets 0.55 mm rods,
9 mm joint cylinders, 3.3 mm end-effector ball -- rods a few pixels wide, joints distinct where
they sit 0.01 m apart."""

SKELETON_STYLE: dict[str, tuple[tuple[float, float, float], str]] = {
    "ground": ((0.62, 0.62, 0.68), "ground link (world origin to the root joints)"),
    "link": ((0.25, 0.25, 0.30), "links"),
    "revolute": ((0.95, 0.55, 0.10), "revolute joints (along the axis)"),
    "prismatic": ((0.15, 0.45, 0.85), "prismatic joints (arrow along the axis)"),
    "closure": ((0.80, 0.10, 0.60), "loop-closure frames"),
    "end_effector": ((0.10, 0.65, 0.25), "end effector"),
}
"""Skeleton part -> (RGB, legend label)."""

_SEGMENT_MIN = 1e-9
"""A link segment shorter than this fraction of L is not drawn (a U or S joint's cross: its joint
origins coincide); a zero-length rod has no direction to draw."""


@dataclass(frozen=True, eq=False)
class SkeletonJoint:
    """A joint of the skeleton: name, "revolute" or "prismatic", world origin [m] and unit axis."""

    name: str
    kind: str
    origin: np.ndarray
    axis: np.ndarray


@dataclass(frozen=True, eq=False)
class Skeleton:
    """What the kinematics knows of a robot at one configuration, for drawing.

    Attributes:
        robot: the robot.
        joints: every joint, in model order.
        segments: (label "parent->child", start, end) [m]: from each body's joint origin to its
            child joints' origins and to its closure / end-effector frames (zero-length ones left out).
        closures: (closure name, frame1 position, frame2 position) [m].
        end_effector: the end-effector frame's position [m].
        length: the model's length scale L [m].
    """

    robot: Any
    joints: tuple[SkeletonJoint, ...]
    segments: tuple[tuple[str, np.ndarray, np.ndarray], ...]
    closures: tuple[tuple[str, np.ndarray, np.ndarray], ...]
    end_effector: np.ndarray
    length: float

    def joint(self, path: str) -> SkeletonJoint:
        """The joint drawn at node path `joints/<k>_<name>`."""
        return self.joints[int(path.split("/", 1)[1].split("_", 1)[0])]

    def points(self) -> np.ndarray:
        """Every point of the skeleton [m] (n, 3)."""
        pts = [j.origin for j in self.joints] + [p for _, a, b in self.segments for p in (a, b)]
        pts += [p for _, a, b in self.closures for p in (a, b)] + [self.end_effector]
        return np.array(pts, dtype=float).reshape(-1, 3)


def skeleton(robot: Any, q: np.ndarray) -> Skeleton:
    """The skeleton of `robot` at Pinocchio configuration q (see `Scene.add_skeleton`). A joint's
    axis is its motion's world direction: the angular part of its Jacobian column for a revolute
    joint, the linear part for a prismatic one."""
    import pinocchio as pin

    from kinematics.generic.serial import length_scale
    from kinematics.model.robot import matrix

    model = robot.model
    data = model.createData()
    q = np.asarray(q, dtype=float)
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    L = length_scale(robot, q)
    joints = []
    for jid in range(1, model.njoints):
        col = matrix(pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED), model.nv)[:, model.joints[jid].idx_v]
        revolute = bool(np.linalg.norm(col[3:]) > 0)
        axis = col[3:] if revolute else col[:3]
        joints.append(SkeletonJoint(model.names[jid], "revolute" if revolute else "prismatic",
                                    data.oMi[jid].translation.copy(), axis / np.linalg.norm(axis)))
    origin = [np.zeros(3)] + [j.origin for j in joints]  # body b's joint origin (0: the world's)
    frames = [(c.name, robot.frame_id(c.frame1), robot.frame_id(c.frame2)) for c in
              (robot.loops.closures if robot.loops is not None else ())]
    ee = robot.frame_id()
    ends: list[tuple[int, str, np.ndarray]] = [(int(model.parents[j]), model.names[j], origin[j])
                                               for j in range(1, model.njoints)]
    for fid in sorted({f for _, a, b in frames for f in (a, b)} | {ee}):
        ends.append((int(model.frames[fid].parentJoint), model.frames[fid].name, data.oMf[fid].translation.copy()))
    parent_name = ["world"] + list(model.names)[1:]
    segments = tuple((f"{parent_name[b]}->{label}", origin[b], end) for b, label, end in ends
                     if np.linalg.norm(end - origin[b]) > _SEGMENT_MIN * L)
    closures = tuple((n, data.oMf[a].translation.copy(), data.oMf[b].translation.copy()) for n, a, b in frames)
    return Skeleton(robot, tuple(joints), segments, closures, data.oMf[ee].translation.copy(), L)


def skeleton_transforms(sk: Skeleton) -> dict[str, np.ndarray]:
    """Node path (under `<robot>_skeleton/`) -> 4 x 4 world transform of every skeleton object.

    Joints: the joint's origin, local y (meshcat's cylinder axis) along the joint's axis. Links: a
    cylinder of height 1 scaled along y to the segment, centred on it, so that local (0, -1/2, 0)
    and (0, 1/2, 0) land on its ends. Balls: their frames' positions."""
    out: dict[str, np.ndarray] = {}
    for k, j in enumerate(sk.joints):
        out[f"joints/{k}_{_node_name(j.name)}"] = _along_y(j.axis, j.origin)
    for k, (label, a, b) in enumerate(sk.segments):
        out[f"links/{k}_{_node_name(label)}"] = _along_y(b - a, (a + b) / 2)
    for name, a, b in sk.closures:
        out[f"closures/{_node_name(name)}_1"] = _translation(*a)
        out[f"closures/{_node_name(name)}_2"] = _translation(*b)
    out["end_effector"] = _translation(*sk.end_effector)
    return out


def _node_name(name: str) -> str:
    return name.replace("/", "_")


def _translation(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _along_y(d: np.ndarray, at: np.ndarray) -> np.ndarray:
    """A transform taking local y to the vector d (its length a scale along y) and the local x, z
    to unit vectors normal to it (right-handed), with its origin at `at`."""
    y = np.asarray(d, dtype=float)
    u = y / np.linalg.norm(y)
    e = np.eye(3)[int(np.argmin(np.abs(u)))]  # the world axis least along d
    x = np.cross(u, e)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, np.cross(x, u), at
    return T


# -- ready-made views -------------------------------------------------------------------------------
NEAR_SINGULAR = 1e-2
"""A pose is flagged "at or near a singularity" when r_min < NEAR_SINGULAR * r_max: the ellipse
is then a sliver nobody can read (at 1e-2, under 3 px on a 0.3 m ellipse in a 600 px view)."""


def default_pose(robot: Any) -> np.ndarray:
    """Joint values [rad or m] to draw a serial robot at when none are given: the middle of the
    joint ranges (a folded, readable pose for most arms), or, if that pose is at or near a
    singularity, the middle moved by alternating +/- min(0.3 half-range, 1 rad) per joint."""
    from kinematics.generic.manipulability import ellipsoid
    from kinematics.generic.serial import task_jacobian

    lo, hi = robot.lower, robot.upper
    bounded = np.isfinite(lo) & np.isfinite(hi)  # a continuous joint's -inf + inf would be NaN
    lo, hi = np.where(bounded, lo, 0.0), np.where(bounded, hi, 0.0)
    mid = (lo + hi) / 2
    step = np.minimum(0.3 * np.where(bounded, (hi - lo) / 2, np.inf), 1.0)
    offset = step * (-1.0) ** np.arange(robot.nv)
    for q in (mid, mid + offset):
        e = ellipsoid(task_jacobian(robot, robot.configuration(q)))
        if e.radii[0] >= NEAR_SINGULAR * e.radii[-1]:
            return q
    return mid + offset


def _check_pose(scene: Scene, radii: np.ndarray, what: str) -> None:
    if radii[0] < NEAR_SINGULAR * radii[-1]:
        scene.warnings.append(f"{what} is at or near a singularity (smallest/largest radius "
                              f"{radii[0] / radii[-1]:.1g}): the ellipse collapses")


def _singular_colours() -> dict[int, tuple[tuple[float, float, float], str]]:
    """Singularity type -> (RGB, label), the colours of `plots.SINGULAR_STYLE`."""
    from matplotlib.colors import to_rgb

    from kinematics.views.plots import SINGULAR_STYLE

    return {k: (to_rgb(c), label) for k, (c, _, label) in SINGULAR_STYLE.items()}


def scara_view(robot: Any, q: np.ndarray | None = None, *, ellipse: bool = False, workspace: bool = False,
               singularities: bool = False, guide: int | None = None, scene: Scene | None = None) -> Scene:
    """The planar arm at q [rad] (default: `default_pose`), with its velocity ellipse at the tool,
    its reachable workspace coloured by the smallest radius, the theta2 = 0 singular arc, or an
    animated guidance run; the camera framed on all of it."""
    from kinematics.generic.manipulability import ellipsoid
    from kinematics.generic.serial import forward_kinematics, task_jacobian
    from kinematics.mechanisms.scara.closed_form import ScaraParams, fk, manipulability
    from kinematics.views.plots import RADIUS_CMAP, SCARA_SINGULAR_COLOUR

    scene = scene or Scene()
    sp = ScaraParams.from_robot(robot)
    qc = robot.configuration(default_pose(robot) if q is None else q)
    scene.add_robot(robot, qc)
    tool = forward_kinematics(robot, qc).position
    e = ellipsoid(task_jacobian(robot, qc))
    if ellipse:
        scene.add_ellipsoid(tool, e.radii, e.directions, "overlays/ellipse",
                            label="velocity ellipse at the tool [m/s per rad/s]")
        _check_pose(scene, e.radii, "this pose")
    if workspace or singularities:
        t1 = np.linspace(sp.lower[0], sp.upper[0], 90)
        t2 = np.linspace(sp.lower[1], sp.upper[1], 90)
        Q = np.stack(np.meshgrid(t1, t2, indexing="ij"), axis=-1).reshape(-1, 2)
        xy = fk(sp, Q)
        if workspace:
            r = manipulability(sp, Q).radii[:, 0]
            scene.add_points(np.hstack([xy, np.full((len(xy), 1), tool[2])]), r, "overlays/workspace",
                             cmap=RADIUS_CMAP, label="reachable points, coloured by the smallest radius [m per rad/s]")
        if singularities:
            from matplotlib.colors import to_rgb

            from kinematics.analyses.singularities import scara_singularities

            pts = scara_singularities(sp)["singular_points"]
            scene.add_points(np.hstack([pts, np.full((len(pts), 1), tool[2] + 0.002)]), name="overlays/singular",
                             colour=to_rgb(SCARA_SINGULAR_COLOUR), size=0.012,
                             label=f"singular: theta2 = 0 ({len(pts)} points)")
    if guide is not None:
        from kinematics.guidance.simulation import run_experiment

        run = run_experiment(guide, sp)
        step = max(1, round(1 / (30 * run.params.dt)))
        scene.animate(robot.name, run.q[::step], 30.0, np.hstack([run.x[::step], np.full((len(run.x[::step]), 1),
                                                                                          tool[2])]))
    scene.fit_camera()
    return scene


VIEW_CELLS = 100_000
"""Points a serial workspace view draws at most (an exported scene stays a few MB)."""


def serial_view(robot: Any, q: np.ndarray | None = None, *, ellipsoid: bool = False, workspace: Any = None,
                singularities: bool = False, scene: Scene | None = None) -> Scene:
    """Any serial robot at joint values q (default: `default_pose`), with the velocity ellipsoid
    of its tool position; with a `SerialWorkspace` (`kinematics.analyses.serial_workspace`), its certified
    cells as points coloured by the smallest radius sigma_min [m/rad] (grey where no configuration
    was evaluated in the cell) and, with `singularities`, the images of the possibly singular
    boxes; the camera framed on all."""
    from kinematics.generic.manipulability import ellipsoid as ellipsoid_of
    from kinematics.generic.serial import forward_kinematics, frame_jacobian

    scene = scene or Scene()
    qc = robot.configuration(default_pose(robot) if q is None else q)
    scene.add_robot(robot, qc)
    if workspace is not None:
        _serial_workspace_points(scene, workspace, singularities)
    if ellipsoid:
        e = ellipsoid_of(frame_jacobian(robot, qc)[:3])
        # true size unless it would dwarf the arm: then scaled to half the arm's bounding radius
        pts = np.vstack(scene._extent)
        size = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) / 4
        scale = min(1.0, size / e.radii[-1])
        label = "velocity ellipsoid of the tool [m/s per rad/s]" if scale == 1 else \
            f"velocity ellipsoid of the tool, scaled x{scale:.2g} (largest radius {e.radii[-1]:.3g} m/s per rad/s)"
        scene.add_ellipsoid(forward_kinematics(robot, qc).position, scale * e.radii, e.directions,
                            "overlays/ellipsoid", label=label)
        _check_pose(scene, e.radii, "this pose")
    scene.fit_camera()
    return scene


def _serial_workspace_points(scene: Scene, w: Any, singularities: bool) -> None:
    """The certified cells (a solid of revolution swept at as many angles as VIEW_CELLS allows)
    coloured by smallest radius, and the singular boxes' images, subsampled evenly to VIEW_CELLS."""
    import dataclasses

    cells = int(w.inside.sum())
    turns = max(4, min(48, VIEW_CELLS // max(cells, 1)))
    pts = w.world_points("inside", turns=turns)
    per = len(pts) // max(cells, 1)  # a revolved cell's points are consecutive
    values = np.repeat(w.smallest_radius[w.inside], per)
    keep = np.unique(np.linspace(0, max(len(pts) - 1, 0), min(len(pts), VIEW_CELLS)).astype(int))
    pts, values = pts[keep], values[keep]
    known = np.isfinite(values)
    size = 1.5 * w.grid.cell
    if known.any():
        scene.add_points(pts[known], values[known], "overlays/workspace", size=size,
                         label=f"smallest radius sigma_min [m/rad] over the certified cells of {w.frame}")
    if (~known).any():
        scene.add_points(pts[~known], None, "overlays/workspace_unsampled", size=size, colour=(0.7, 0.7, 0.7),
                         opacity=0.4, label="certified cells where no configuration was evaluated")
    if singularities and len(w.singular_radius):
        k = len(w.singular_radius)
        idx = np.unique(np.linspace(0, k - 1, min(k, VIEW_CELLS // (5 if w.mode != "revolved" else 40))).astype(int))
        sing = dataclasses.replace(w, singular_points=w.singular_points[idx]).world_points("singular", turns=8)
        scene.add_points(sing, None, "overlays/singular", size=size, colour=(0.85, 0.1, 0.1),
                         label=f"possibly singular boxes' images ({k:,} boxes, sample of {len(idx):,})")


def closed_loop_view(robot: Any, actuators: np.ndarray | None = None, *, workspace: bool = False,
                     singularities: bool = False, limits: str = "all", step: float = 0.05,
                     scene: Scene | None = None) -> Scene:
    """Any URDF + loop sidecar through the generic Pinocchio closed-loop solver: at the sidecar's
    reference configuration, or assembled from actuator values [rad or m]; optionally its workspace
    (grid step `step` [m], through the mechanism's margin: `kinematics.mechanisms.closed_loop`'s
    batched solver, every branch) coloured by conditioning, and its singular points where the
    mechanism gives singular fields; camera framed on all of it. A planar task space is drawn in
    the plane of the end effector's reference position."""
    from kinematics.generic.closedloop import ClosedLoop
    from kinematics.mechanisms import mechanism_of

    scene = scene or Scene()
    loop = ClosedLoop(robot)
    q, note = closed_loop_pose(robot, loop, actuators)
    scene.add_robot(robot, q)
    scene.warnings += [note] if note else []
    _check_closed(scene, robot, loop, q)
    if workspace or singularities:
        import pinocchio as pin

        data = robot.model.createData()
        pin.framesForwardKinematics(robot.model, data, loop.reference)
        at = np.asarray(data.oMf[robot.frame_id()].translation, dtype=float)
        mech = mechanism_of(robot)
        _mechanism_overlays(scene, mech, at, workspace=workspace, singularities=singularities, limits=limits, step=step)
        if mech.task_dim == 2:  # look down on a planar workspace
            scene.fit_camera(direction=(0.4, -0.6, 1.0))
            return scene
    scene.fit_camera(direction=_facing(robot, q) if robot.name in scene.skeletons else (1.0, -1.4, 0.9))
    return scene


def _facing(robot: Any, q: np.ndarray) -> tuple[float, float, float]:
    """A camera direction for a skeleton: a planar mechanism seen from in front of its plane
    (along the normal, turned 22 deg sideways and 17 deg up so the joints' cylinders show as
    cylinders); a spatial one from the usual (1, -1.4, 0.9)."""
    from kinematics.generic.serial import common_axis

    n = common_axis(robot.model, q)
    if n is None:
        return (1.0, -1.4, 0.9)
    z = np.array([0.0, 0.0, 1.0])
    if abs(n[2]) > 0.9:  # a horizontal plane: from above
        return (0.4, -0.6, 1.0)
    side = np.cross(z, n)
    d = n - 0.4 * side / np.linalg.norm(side) + 0.3 * z
    return (float(d[0]), float(d[1]), float(d[2]))


def closed_loop_pose(robot: Any, loop: Any, actuators: np.ndarray | None) -> tuple[np.ndarray, str | None]:
    """The configuration a closed-loop model is drawn at, and what the reader must know about it.

    The single place the view's pose is chosen: assembled from `actuators` [rad or m] (the loops
    closed with them held; `ClosedLoop.solve(..., fallback=True)`), else `ClosedLoop.assembly`,
    the sidecar's reference closed by `kinematics.generic.assembly.assemble` where it is open (the
    neutral pose where the sidecar names none, e.g. a Gepetto `robot.yaml`: most Gepetto models
    are exported open at q = 0). Where no closed pose is found the start is drawn, open.

    Returns:
        (Pinocchio configuration, a warning or None).
    """
    from kinematics.generic.assembly import AssemblyError

    if actuators is not None:
        return np.asarray(loop.solve(np.asarray(actuators, dtype=float), fallback=True).q), None
    try:
        found = loop.assembly
    except AssemblyError as exc:
        values = np.zeros(robot.nv)
        for name, value in loop.spec.reference.items():
            values[robot.joint_names.index(name)] = value
        where = "its sidecar's reference" if loop.spec.reference else "the neutral pose (q = 0)"
        return robot.configuration(values), f"{robot.name}: no closed pose found ({exc}); drawn open at {where}"
    note = f"{robot.name}: drawn at {found.description}" if found.found else None
    return np.asarray(found.q), note


OPEN_LOOP_RTOL = 1e-6
"""A drawn closed-loop pose is flagged as open when its largest closure error exceeds this
fraction of the model's length scale: above what a hand-typed reference (6-8 digits) leaves,
far below the assemblies' 1e-10 (`generic.assembly.TOLERANCE`)."""


def _check_closed(scene: Scene, robot: Any, loop: Any, q: np.ndarray) -> None:
    from kinematics.generic.serial import length_scale

    gap = float(np.abs(loop.residual(q)[0]).max()) if loop.n_constraints else 0.0
    if gap > OPEN_LOOP_RTOL * length_scale(robot, q):
        scene.warnings.append(f"{robot.name}: the loops are not closed at the drawn pose (largest closure error "
                              f"{gap:.3g} m or rad)")


def _embed(mech: Any, points: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Task points (N, d) as world points (N, 3): the axes the task lacks stay at `at` [m]."""
    axes = ["xyz".index(a) for a in mech.task_axes]
    out = np.tile(np.asarray(at, dtype=float), (len(points), 1))
    out[:, axes] = points
    return out


def _mechanism_overlays(scene: Scene, mech: Any, at: np.ndarray, *, workspace: bool, singularities: bool,
                        limits: str, step: float) -> None:
    """The workspace (grid points inside some branch, coloured by min(iota_I, iota_II) of the
    best-conditioned branch) and the singular points by type, of any mechanism with a margin
    (and velocity; singular fields for the loci)."""
    from kinematics.sizes import MAX_VIEW_POINTS, check_points, grid_points
    from kinematics.views.plots import CONDITIONING_CMAP, LIMITS_TEXT

    if workspace:
        mech.require("margin", "a workspace view")
        lo, hi = mech.bounding_box(limits)
        check_points("step", grid_points(lo, hi, step), limit=MAX_VIEW_POINTS,
                     hint=f"{step:g} m is too fine a step for a view")
        axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(len(lo))]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(lo))
        margin = mech.margin(None, limits)(pts)[:, :-1]
        pts = pts[(margin >= 0).any(axis=1)]
        cond = np.full(len(pts), -1.0)
        if "velocity" in mech.capabilities and len(pts):
            for b in mech.branches:
                v, ok = mech.branch_velocity(pts, b, limits)
                cond = np.where(ok, np.fmax(cond, np.minimum(v.iota_I, v.iota_II)), cond)
        # small, half-transparent points: the robot stays visible inside its workspace
        scene.add_points(_embed(mech, pts, at), cond, "overlays/workspace", size=step * 0.35,
                         cmap=CONDITIONING_CMAP, vrange=(0.0, 1.0), opacity=0.5,
                         label=f"workspace ({LIMITS_TEXT.get(limits, limits)}), coloured by min(\u03b9_I, \u03b9_II), "
                               "0 = singular")
    if singularities:
        from kinematics.analyses.singularities import singular_loci

        mech.require("singular_fields", "a view of singular loci")
        loc = singular_loci(mech, step=step, limits=limits, progress=False).locus
        for k, (rgb, label) in _singular_colours().items():
            sel = loc.inside & (loc.kind == k)
            if sel.any():
                # type I outlines the whole boundary: small and faint, so II / III and the robot show
                scene.add_points(_embed(mech, loc.points[sel][:, :mech.task_dim], at), name=f"overlays/singular_{k}",
                                 colour=rgb, size=0.006 if k == 1 else 0.009, opacity=0.35 if k == 1 else 1.0,
                                 label=f"{label} singular points {'on' if k == 1 else 'in'} the workspace: "
                                       f"{int(sel.sum())}")


def parallel_view(robot: Any, position: np.ndarray | None = None, mode: str = "---",
                  actuators: np.ndarray | None = None, *, ellipsoid: bool = False, workspace: bool = False,
                  singularities: bool = False, limits: str = "all", step: float = 0.02,
                  scene: Scene | None = None) -> Scene:
    """A closed-form parallel robot (the 3-[P2(US)], the Delta: any mechanism with ik, velocity
    and joint values) at a platform position (closed forms -> actuators -> Pinocchio closed-loop
    solve) or at actuator values, with its velocity ellipsoid (from J), its workspace as a point
    cloud coloured by the conditioning min(iota_I, iota_II) of the best-conditioned branch, and
    its singular points by type; the camera framed on all of it, a warning when the pose is
    singular."""
    from kinematics.generic.closedloop import ClosedLoop
    from kinematics.generic.manipulability import ellipsoid as ellipsoid_of
    from kinematics.mechanisms import SINGULARITY_TYPES, mechanism_of

    scene = scene or Scene()
    mech = mechanism_of(robot)
    for need in ("ik", "velocity", "joint_values"):
        mech.require(need, "a view of a parallel robot")
    loop = ClosedLoop(robot)
    branches = mech.branches
    if actuators is None:
        if position is None:
            position, mode = mech.reference_pose()
        p = np.asarray(position, dtype=float)
        m = branches.index(mech.check_branches([mode])[0])
        sol = mech.ik(p[None])
        if not sol.reachable[0, m]:
            raise InvalidInputError("position", f"{p.tolist()} is not reachable in {mech.branch_kind} {mode}")
        values = mech.joint_values(p, mode)
        warm = robot.configuration([values[n] for n in robot.joint_names])
        res = loop.solve(sol.q[0, m], q0=warm)
    else:
        res = loop.solve(np.asarray(actuators, dtype=float))
    scene.add_robot(robot, res.q)
    p = np.asarray(res.pose.translation, dtype=float)
    s = mech.ik(p[None])
    m = (branches.index(mode) if actuators is None
         else int(np.nanargmin(np.abs(s.q[0] - np.asarray(actuators, dtype=float)).sum(axis=-1))))
    vel = mech.velocity(p[None], s.q[0, m][None])
    kind = int(vel.types[0])
    if kind:
        scene.warnings.append(f"this pose is singular ({SINGULARITY_TYPES[kind]}: iota_I = {float(vel.iota_I[0]):.2g}, "
                              f"iota_II = {float(vel.iota_II[0]):.2g})")
    if ellipsoid:
        if kind >= 2:
            raise InvalidInputError("position", "J_x is singular (type II): no velocity ellipsoid here")
        e = ellipsoid_of(vel.J[0])
        scene.add_ellipsoid(p, 0.1 * e.radii / e.radii.max(), e.directions, "overlays/ellipsoid",
                            label="velocity ellipsoid of the platform (largest radius drawn 0.1 m)")
    if workspace or singularities:
        _mechanism_overlays(scene, mech, p, workspace=workspace, singularities=singularities, limits=limits,
                            step=step)
    # a low camera: the base disk hangs above the mechanism and hides it from the usual 30 deg
    scene.fit_camera(direction=(1.0, -1.4, 0.2))
    return scene


def conditioning_view(mech: Any, branch: str, *, limits: str = "all", step: float | None = None,
                      scene: Scene | None = None) -> Scene:
    """A mechanism's workspace (one branch, or "union": the best branch at each point) as points
    coloured by 1/kappa of the forward Jacobian (0 singular, 1 isotropic); camera framed on them."""
    from kinematics.analyses.dexterity import conditioning_grid
    from kinematics.sizes import MAX_VIEW_POINTS, check_points
    from kinematics.views.plots import INVERSE_KAPPA_CMAP, LIMITS_TEXT

    scene = scene or Scene()
    axes, g = conditioning_grid(mech, branch, limits=limits, step=step)
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(axes))
    step = float(axes[0][1] - axes[0][0]) if len(axes[0]) > 1 else 0.01
    v = g.ravel()
    keep = np.isfinite(v)
    check_points("step", int(keep.sum()), limit=MAX_VIEW_POINTS, hint="use a larger step")
    scene.add_points(pts[keep], v[keep], "overlays/conditioning", size=step * 0.4, cmap=INVERSE_KAPPA_CMAP,
                     vrange=(0.0, 1.0), opacity=0.6,
                     label=f"1/\u03ba of J, {mech.branch_kind} {branch} ({LIMITS_TEXT.get(limits, limits)})")
    scene.fit_camera()
    return scene

