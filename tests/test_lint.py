"""ruff, mypy and import-linter run clean over the project, with the versions the test extras pin
(so a newer release's defaults cannot turn the suite red, and a finding cannot land unnoticed),
and no private name crosses a module boundary."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _tool(name: str) -> str:
    path = shutil.which(name, path=str(Path(sys.executable).parent)) or shutil.which(name)
    if path is None:
        pytest.fail(f"{name} is not installed: `pip install -e '.[test]'` brings it")
    return path


def test_ruff_is_clean():
    run = subprocess.run([_tool("ruff"), "check", "--no-cache", "."], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


@pytest.mark.slow
def test_mypy_is_clean():
    run = subprocess.run([_tool("mypy"), "kinematics"], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def test_import_layers_hold():
    """pyproject's [tool.importlinter] contracts: cli > views > guidance > analyses > mechanisms >
    generic > model, the foundation modules import no layer, the robot families are independent."""
    run = subprocess.run([_tool("lint-imports"), "--no-cache"], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


def _private_crossings(source: str, where: str) -> list[str]:
    """`from kinematics... import _name` and `module._name` on an imported kinematics module."""
    tree = ast.parse(source)
    found, modules = [], set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("kinematics"):
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__"):
                    found.append(f"{where}:{node.lineno}: from {node.module} import {a.name}")
                modules.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            modules |= {a.asname or a.name.split(".")[0] for a in node.names if a.name.startswith("kinematics")}
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in modules
                and node.attr.startswith("_") and not node.attr.startswith("__")):
            found.append(f"{where}:{node.lineno}: {node.value.id}.{node.attr}")
    return found


def test_the_private_name_check_sees_both_forms():
    src = "from kinematics.x import _a, b\nimport kinematics.y as y\ny._c()\nself._d = 1\n"
    assert _private_crossings(src, "s") == ["s:1: from kinematics.x import _a", "s:3: y._c"]


def test_no_private_name_crosses_a_module():
    found = [hit for f in sorted((ROOT / "kinematics").rglob("*.py"))
             for hit in _private_crossings(f.read_text(), str(f.relative_to(ROOT)))]
    assert not found, "\n".join(found)
