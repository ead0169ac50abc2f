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
from typing import Any

import numpy as np

from .errors import InvalidInputError

ROBOT_COLOURS = {"scara": (0.85, 0.45, 0.1), "p2us": (0.2, 0.45, 0.8)}


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
    """

    def __init__(self, live: bool = False) -> None:
        import meshcat

        self.live = live
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
    def camera(self, position: Sequence[float], target: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Place the default camera (world z up) [m]. Pinocchio's setters fail with meshcat 0.3.2;
        meshcat's camera node is y-up, so the position is given in its frame."""
        import meshcat.transformations as tf

        t = np.asarray(target, dtype=float)
        p = np.asarray(position, dtype=float) - t
        self.vis["/Cameras/default"].set_transform(tf.translation_matrix(t))
        self.vis["/Cameras/default/rotated/<object>"].set_property("position", [float(p[0]), float(p[2]), float(-p[1])])

    # -- robots ----------------------------------------------------------------------------------
    def add_robot(self, robot: Any, q: np.ndarray, name: str | None = None,
                  colour: Sequence[float] | None = None) -> Any:
        """Draw `robot` (a `kinematics.model.Robot`) at configuration q from its URDF visuals."""
        import pinocchio as pin
        from pinocchio.visualize import MeshcatVisualizer

        name = name or robot.name
        visual = pin.buildGeomFromUrdf(robot.model, str(robot.urdf_path), pin.GeometryType.VISUAL,
                                       package_dirs=list(robot.package_dirs) or None)
        rgb = colour or ROBOT_COLOURS.get(robot.name)
        if rgb is not None:
            for g in visual.geometryObjects:
                if g.meshPath in ("", "BOX", "CYLINDER", "SPHERE") or not os.path.exists(g.meshPath):
                    g.meshColor = np.array([*rgb, 1.0])
        viz = MeshcatVisualizer(robot.model, pin.GeometryModel(), visual)
        viz.initViewer(viewer=self.vis)
        viz.loadViewerModel(rootNodeName=name)
        viz.display(np.asarray(q, dtype=float))
        self.robots[name] = viz
        self.configurations[name] = np.asarray(q, dtype=float).copy()
        return viz

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
        finally:
            viz.viewer = saved
        if trace is not None:
            self.add_line(trace, f"overlays/{name}_trace", (0.1, 0.6, 0.2))
        self.vis.set_animation(anim, play=True, repetitions=1)

    # -- overlays ------------------------------------------------------------------------------
    def add_ellipsoid(self, centre: Sequence[float], radii: Sequence[float], directions: np.ndarray,
                      name: str = "overlays/ellipsoid", colour: Sequence[float] = (0.9, 0.2, 0.2),
                      opacity: float = 0.4) -> None:
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

    def add_points(self, points: np.ndarray, values: np.ndarray | None = None, name: str = "overlays/points",
                   size: float = 0.006, cmap: str = "viridis", colour: Sequence[float] = (0.1, 0.1, 0.1),
                   vrange: tuple[float, float] | None = None) -> None:
        """A point cloud [m], coloured by `values` through a matplotlib colour map (or one colour)."""
        import meshcat.geometry as mg

        P = np.asarray(points, dtype=float)
        if P.ndim != 2 or P.shape[1] not in (2, 3):
            raise InvalidInputError("points", f"expected (N, 2) or (N, 3), got {P.shape}")
        if P.shape[1] == 2:
            P = np.hstack([P, np.zeros((len(P), 1))])
        if values is None:
            C = np.tile(np.asarray(colour, dtype=float), (len(P), 1))
        else:
            from matplotlib import colormaps

            v = np.asarray(values, dtype=float)
            lo, hi = vrange or (float(np.min(v)), float(np.max(v)))
            C = colormaps[cmap]((v - lo) / (hi - lo if hi > lo else 1.0))[:, :3]
        self.vis[name].set_object(mg.PointCloud(P.T.astype(np.float32), C.T.astype(np.float32), size=size))

    def add_line(self, points: np.ndarray, name: str, colour: Sequence[float] = (0.1, 0.6, 0.2)) -> None:
        import meshcat.geometry as mg

        P = np.asarray(points, dtype=float)
        if P.shape[1] == 2:
            P = np.hstack([P, np.zeros((len(P), 1))])
        self.vis[name].set_object(mg.Line(mg.PointsGeometry(P.T.astype(np.float32)),
                                          mg.LineBasicMaterial(color=_hex(colour))))

    # -- output ------------------------------------------------------------------------------------
    def html(self) -> str:
        """A self-contained HTML page of the scene (viewer JavaScript and commands inlined)."""
        if self.live:
            return self.vis.static_html()
        cmds = "\n".join(
            "viewer.handle_command_bytearray(Uint8Array.from(atob(\"{}\"), c => c.charCodeAt(0)));".format(
                base64.b64encode(c).decode("ascii"))
            for c in self._window.commands()
        )
        return (
            "<!DOCTYPE html>\n<html><head><meta charset=utf-8><title>kinematics - meshcat</title>\n"
            "<style>body{margin:0} #meshcat-pane{width:100vw;height:100vh;overflow:hidden}</style></head>\n"
            "<body><div id=\"meshcat-pane\"></div>\n<script>\n" + _viewer_js() + "\n</script>\n<script>\n"
            "var viewer = new MeshCat.Viewer(document.getElementById(\"meshcat-pane\"));\n" + cmds
            + "\n</script></body></html>\n"
        )

    def export(self, path: str | os.PathLike[str]) -> None:
        """Write `html()` to a file (atomically)."""
        from .report import write_atomic

        write_atomic(os.fspath(path), self.html(), "--export")

    def notebook(self, height: int = 420) -> Any:
        """An IPython HTML object embedding the scene (an iframe with the page inlined)."""
        from IPython.display import HTML

        doc = html_lib.escape(self.html(), quote=True)
        return HTML(f'<iframe srcdoc="{doc}" style="width:100%;height:{height}px;border:none"></iframe>')


def _hex(rgb: Sequence[float]) -> int:
    r, g, b = (int(round(255 * max(0.0, min(1.0, c)))) for c in rgb[:3])
    return (r << 16) | (g << 8) | b


# -- ready-made views -------------------------------------------------------------------------------
def scara_view(robot: Any, q: np.ndarray, *, ellipse: bool = False, workspace: bool = False,
               singularities: bool = False, guide: int | None = None, scene: Scene | None = None) -> Scene:
    """The planar arm at q [rad], with its velocity ellipse at the tool, its reachable workspace
    coloured by the smallest radius, the theta2 = 0 singular arc, or an animated guidance run."""
    from .manipulability import ellipsoid
    from .scara import ScaraParams, fk, manipulability
    from .serial import forward_kinematics, task_jacobian

    scene = scene or Scene()
    sp = ScaraParams.from_robot(robot)
    qc = robot.configuration(q)
    scene.add_robot(robot, qc)
    tool = forward_kinematics(robot, qc).position
    if ellipse:
        e = ellipsoid(task_jacobian(robot, qc))
        scene.add_ellipsoid(tool, e.radii, e.directions, "overlays/ellipse")
    if workspace or singularities:
        t1 = np.linspace(sp.lower[0], sp.upper[0], 90)
        t2 = np.linspace(sp.lower[1], sp.upper[1], 90)
        Q = np.stack(np.meshgrid(t1, t2, indexing="ij"), axis=-1).reshape(-1, 2)
        xy = fk(sp, Q)
        if workspace:
            r = manipulability(sp, Q).radii[:, 0]
            scene.add_points(np.hstack([xy, np.full((len(xy), 1), tool[2])]), r, "overlays/workspace", cmap="magma")
        if singularities:
            from .singularities import scara_singularities

            pts = scara_singularities(sp)["singular_points"]
            scene.add_points(np.hstack([pts, np.full((len(pts), 1), tool[2])]), name="overlays/singular",
                             colour=(0.0, 0.8, 0.9), size=0.012)
    if guide is not None:
        from .guidance_sim import run_experiment

        run = run_experiment(guide, sp)
        step = max(1, int(round(1 / (30 * run.params.dt))))
        scene.animate(robot.name, run.q[::step], 30.0, np.hstack([run.x[::step], np.full((len(run.x[::step]), 1),
                                                                                          tool[2])]))
    scene.camera((0.3, -1.2, 1.2), (0.3, 0.0, 0.0))
    return scene


def p2us_view(robot: Any, position: np.ndarray | None = None, mode: str = "---", actuators: np.ndarray | None = None,
              *, ellipsoid: bool = False, workspace: bool = False, singularities: bool = False,
              limits: str = "all", step: float = 0.02, scene: Scene | None = None) -> Scene:
    """The 3-[P2(US)] at a platform position (closed forms -> actuators -> Pinocchio closed-loop
    solve) or at actuator values, with its velocity ellipsoid (from J^-1), its workspace as a point
    cloud coloured by the conditioning min(iota_I, iota_II), and its singular points."""
    from .closedloop import ClosedLoop
    from .manipulability import ellipsoid as ellipsoid_of
    from .p2us_urdf import joint_values_at, reference_pose
    from .parallel import ik, jacobian_inverse, mode_index
    from .parallel_cli import params_of

    scene = scene or Scene()
    P = params_of(robot)
    loop = ClosedLoop(robot)
    if actuators is None:
        if position is None:
            position, mode = reference_pose(P)
        p = np.asarray(position, dtype=float)
        sol = ik(P, p)
        m = mode_index(mode)
        if not sol.reachable[m]:
            raise InvalidInputError("position", f"{p.tolist()} is not reachable in mode {mode}")
        values = joint_values_at(P, p, mode)
        warm = robot.configuration([values[n] for n in robot.joint_names])
        res = loop.solve(sol.q[m], q0=warm)
    else:
        res = loop.solve(np.asarray(actuators, dtype=float))
    scene.add_robot(robot, res.q)
    p = res.pose.translation
    if ellipsoid:
        s = ik(P, p)
        m = mode_index(mode) if actuators is None else int(np.nanargmin(np.abs(s.q - actuators).sum(axis=-1)))
        e = ellipsoid_of(jacobian_inverse(P, p, s.q[m]))
        scene.add_ellipsoid(p, 0.1 * e.radii / e.radii.max(), e.directions, "overlays/ellipsoid")
    if workspace:
        from .p2us_scan import bounding_box, scan

        lo, hi = bounding_box(P)
        axes = [np.arange(lo[k] + step / 2, hi[k], step) for k in range(3)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        r = scan(P, pts, limits)
        inside = r.margin >= 0
        iota_I = np.sqrt(np.maximum(r.disc.min(axis=1), 0)) / P.L
        cond = np.where(inside, np.minimum(np.abs(r.det), iota_I[:, None]), -1).max(axis=1)
        keep = inside.any(axis=1)
        scene.add_points(pts[keep], cond[keep], "overlays/workspace", size=step * 0.6, vrange=(0.0, 1.0))
    if singularities:
        from .singularities import p2us_singularities

        loc = p2us_singularities(P, step=step, limits=limits, progress=False).locus
        near = loc.inside
        scene.add_points(loc.points[near], name="overlays/singular", colour=(0.9, 0.1, 0.1), size=0.012)
    scene.camera((1.1, -1.1, 0.4), (0.0, 0.0, -0.35))
    return scene
