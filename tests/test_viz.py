"""Meshcat scenes, `kinematics show`, and a real headless browser drawing both robots."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from kinematics import viz

from .test_cli import run

BROWSER = shutil.which("chromium-headless-shell") or shutil.which("chromium")
REQUIRE = os.environ.get("KINEMATICS_REQUIRE_BROWSER") == "1"


def test_scene_records_commands(scara, p2us):
    s = viz.scara_view(scara, [0.3, -1.0], ellipse=True, workspace=True, singularities=True, guide=2)
    html = s.html()
    assert "MeshCat.Viewer" in html and html.count("handle_command_bytearray") > 10
    assert "http://" not in html.split("<script>", 1)[0]  # self-contained: no external loads in the head
    root = s._window.tree["meshcat"]
    assert len(list(root["scara"]["visuals"])) >= 5  # the robot's link geometries
    assert {"ellipse", "workspace", "singular", "scara_trace"} <= set(root["overlays"])
    assert any(n.animation is not None for n in _walk(s._window.tree))
    s2 = viz.p2us_view(p2us, [0.05, 0.0, -0.45], ellipsoid=True, workspace=True, step=0.04)
    assert {"ellipsoid", "workspace"} <= set(s2._window.tree["meshcat"]["overlays"])


def _walk(tree):
    from meshcat.servers.tree import walk

    return walk(tree)


def test_p2us_view_is_closed_loop_solved(p2us):
    from kinematics.closedloop import ClosedLoop

    p = np.array([0.05, -0.02, -0.45])
    s = viz.p2us_view(p2us, p)
    q = s.configurations["p2us"]
    loop = ClosedLoop(p2us)
    assert np.linalg.norm(loop.residual(q)[0]) < 1e-9  # every loop closed
    from kinematics.serial import forward_kinematics

    np.testing.assert_allclose(forward_kinematics(p2us, q).position, p, atol=1e-9)


def test_show_export_and_errors(capsys, tmp_path):
    out = tmp_path / "s.html"
    code, text, _ = run(capsys, "show", "scara", "--q", "20", "-60", "--degrees", "--ellipsoid", "--export", str(out))
    assert code == 0 and out.exists() and str(out) in text
    code, text, err = run(capsys, "show", "p2us", "--position", "0.9", "0", "-0.3", "--export", str(out))
    assert code == 1 and "NOT reachable" in text and err == ""  # unreachable: an answer, as in ik
    code, _, err = run(capsys, "show", "ur5", "--workspace", "--export", str(out))
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_show_serves_until_interrupted():
    """The live viewer answers HTTP, and the meshcat server dies with the command."""
    exe = Path(sys.executable).parent / "kinematics"
    proc = subprocess.Popen([str(exe), "show", "scara", "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stdout.readline()
        import json

        url = json.loads(line + proc.stdout.readline() + proc.stdout.readline() + proc.stdout.readline())["url"]
        assert url.startswith("http://127.0.0.1:")
        body = urllib.request.urlopen(url, timeout=10).read()
        assert b"meshcat" in body.lower()
        children = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
        assert children, "meshcat's server runs as a child process"
        proc.send_signal(signal.SIGTERM)
        proc.wait(15)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(Path(f"/proc/{c}").exists() for c in children):
            time.sleep(0.1)
        assert not any(_alive(c) for c in children), "the meshcat server outlived `kinematics show`"
    finally:
        if proc.poll() is None:
            proc.kill()


def _alive(pid: str) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split()[2]
    except OSError:
        return False
    return state != "Z"


def _screenshot(html: Path, png: Path, tmp: Path) -> np.ndarray:
    from matplotlib.image import imread

    cmd = [BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
           "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", "--no-first-run", f"--user-data-dir={tmp / 'profile'}", "--window-size=800,600",
           "--virtual-time-budget=8000", f"--screenshot={png}", html.as_uri()]
    subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    return imread(png)[..., :3]


@pytest.mark.skipif(BROWSER is None and not REQUIRE, reason="no headless Chromium here (.ci/run installs it)")
@pytest.mark.parametrize("name", ["scara", "p2us"])
def test_robot_is_drawn_in_a_real_browser(tmp_path, name, scara, p2us):
    assert BROWSER is not None, "KINEMATICS_REQUIRE_BROWSER=1 but chromium-headless-shell is missing"
    robot = scara if name == "scara" else p2us
    scene = viz.scara_view(robot, [0.3, -1.0]) if name == "scara" else viz.p2us_view(robot)
    empty = viz.Scene()
    if name == "scara":
        empty.camera((0.3, -1.2, 1.2), (0.3, 0.0, 0.0))
    else:
        empty.camera((1.1, -1.1, 0.4), (0.0, 0.0, -0.35))
    scene.export(tmp_path / "robot.html")
    empty.export(tmp_path / "empty.html")
    a = _screenshot(tmp_path / "robot.html", tmp_path / "robot.png", tmp_path)
    b = _screenshot(tmp_path / "empty.html", tmp_path / "empty.png", tmp_path)
    assert a.shape == b.shape == (600, 800, 3)
    diff = np.abs(a - b).max(axis=-1) > 0.1
    h, w = diff.shape
    centre = diff[h // 4: 3 * h // 4, w // 4: 3 * w // 4]
    assert centre.mean() > 0.02, "the robot is not drawn in the middle of the view"
    assert diff[: h // 8].mean() < 0.2 * centre.mean() + 0.01  # and not everywhere (same camera, same sky)
    colour = np.array(viz.ROBOT_COLOURS[name])
    close = np.linalg.norm(a - colour, axis=-1) < 0.25
    assert close[h // 4: 3 * h // 4, w // 4: 3 * w // 4].sum() > 200, "no pixel has the robot's colour"
