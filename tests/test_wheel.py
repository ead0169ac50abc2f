"""The built wheel is the whole package: built from the tracked files, installed (not editable) in a
fresh virtual environment, it holds every module and data file of the source tree and runs a serial
arm, the Delta and a generic closed loop from outside the repository.

The new environment sees the current one's installed dependencies through a `.pth` file that lists
the current `sys.path` directories (minus any that hold a `kinematics/` folder). A directory added
by a `.pth` file is not scanned for `.pth` files itself, so the editable install's finder
(`__editable__...pth`) stays inactive there: the test checks that `kinematics` cannot be imported
before the wheel is installed.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FOURBAR = ROOT / "tests" / "models" / "fourbar.urdf"
# (command line, JSON keys compared with the source tree's own output)
COMMANDS = [
    (["fk", "ur5", "--q", "0", "0", "0", "0", "0", "0", "--json"], ("frame", "position", "rotation")),  # serial arm
    (["ik", "delta", "--position", "0", "0", "-0.85", "--json"], ("reachable", "solutions")),  # Delta
    (["fk", str(FOURBAR), "--q", "0.3", "--json"], ("position", "residual", "joint_values")),  # generic loop
]


def _can_build_wheels() -> bool:
    """setuptools >= 70.1 builds wheels itself; older ones need the `wheel` package."""
    try:
        import setuptools
    except ImportError:
        return False
    major, minor = (int(p) for p in setuptools.__version__.split(".")[:2])
    if (major, minor) >= (70, 1):
        return True
    try:
        import wheel  # noqa: F401
    except ImportError:
        return False
    return True


def _tracked_files() -> list[str]:
    if shutil.which("git") is None:
        pytest.skip("git is not installed: the tracked files cannot be listed")
    out = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], capture_output=True, text=True)
    if out.returncode != 0:
        pytest.skip(f"not a git checkout: {out.stderr.strip()}")
    return [f for f in out.stdout.split("\0") if f]


def _close(a: object, b: object, tol: float = 1e-12) -> bool:
    """Same JSON value, numbers within tol (relative, absolute below 1)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k], tol) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y, tol) for x, y in zip(a, b, strict=True))
    if isinstance(a, float | int) and isinstance(b, float | int) and not isinstance(a, bool):
        return abs(a - b) <= tol * max(1.0, abs(a), abs(b))
    return a == b


def _source_output(argv: list[str]) -> dict:
    from kinematics.cli.app import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.suppress(SystemExit):
        main(argv)
    return json.loads(buf.getvalue())


@pytest.mark.slow
def test_wheel_installs_and_runs_outside_the_repository(tmp_path):
    if not _can_build_wheels():
        pytest.skip("building a wheel without isolation needs setuptools>=70.1 (or the wheel package): "
                    "pip install -e '.[test]'")
    src = tmp_path / "src"
    for name in _tracked_files():
        if (ROOT / name).is_file():
            (src / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, src / name)

    dist = tmp_path / "dist"
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "--no-index",
                            "-q", "-w", str(dist), "."], cwd=src, capture_output=True, text=True)
    assert build.returncode == 0, build.stdout + build.stderr
    (whl,) = dist.glob("kinematics-*.whl")

    # -- contents: every module and package of the source tree, the URDFs, py.typed ----------------
    names = set(zipfile.ZipFile(whl).namelist())
    modules = {str(p.relative_to(src)) for ext in ("*.py", "*.pyi") for p in (src / "kinematics").rglob(ext)}
    assert any(m.endswith("mechanisms/serial/__init__.py") for m in modules)  # the list below is not empty
    assert "kinematics/analyses/__init__.pyi" in modules  # the public names lazy_loader reads at import
    assert sorted(modules - names) == [], "modules missing from the wheel"
    packages = {str(p.parent.relative_to(src)) for p in (src / "kinematics").rglob("__init__.py")}
    assert {"kinematics/mechanisms/serial", "kinematics/mechanisms/closed_loop"} <= packages
    data = {f"kinematics/urdf/{p.name}" for p in (src / "urdf").iterdir() if p.suffix in (".urdf", ".yaml")}
    assert "kinematics/urdf/p2us.urdf" in data
    assert sorted((data | {"kinematics/py.typed"}) - names) == []

    # -- a fresh environment that sees the installed dependencies but not the editable install ---
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    visible = [p for p in dict.fromkeys(sys.path) if p and Path(p).is_dir() and not (Path(p) / "kinematics").exists()]
    Path(site, "parent_env.pth").write_text("\n".join(visible) + "\n")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP")}
    run = tmp_path / "elsewhere"  # not the repository, so no `kinematics/` in the working directory
    run.mkdir()

    def python(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([str(py), *args], cwd=run, env=env, capture_output=True, text=True)

    before = python("-c", "import importlib.util, pinocchio; print(importlib.util.find_spec('kinematics'))")
    assert before.returncode == 0, before.stderr  # the dependencies are visible ...
    assert before.stdout.strip() == "None"  # ... and the editable kinematics is not

    install = python("-m", "pip", "install", "--no-deps", "--no-index", "--ignore-installed", "-q", str(whl))
    assert install.returncode == 0, install.stdout + install.stderr
    where = python("-c", "import kinematics, kinematics.model.robot as r; print(kinematics.__file__); print(r.URDF_DIR)")
    assert where.returncode == 0, where.stderr
    module, urdf_dir = (Path(p).resolve() for p in where.stdout.split())
    assert module.is_relative_to(Path(site).resolve()), module
    assert urdf_dir == Path(site).resolve() / "kinematics" / "urdf"

    # -- the installed console script on a serial arm, the Delta, a generic closed loop ---------
    script = venv / "bin" / "kinematics"
    assert script.exists()
    for argv, keys in COMMANDS:
        out = subprocess.run([str(script), *argv], cwd=run, env=env, capture_output=True, text=True)
        assert out.returncode == 0, f"{argv}: {out.stderr}"
        got, want = json.loads(out.stdout), _source_output(argv)
        for k in keys:
            assert _close(got[k], want[k]), (argv, k, got[k], want[k])
    # python -m kinematics too, and `info` of the closed loop (its sidecar read by the installed code)
    info = python("-m", "kinematics", "info", str(FOURBAR), "--json")
    assert info.returncode == 0, info.stderr
    assert json.loads(info.stdout)["mobility"] == 1
