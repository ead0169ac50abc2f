"""The set-up contract: CI runs the README's test command, and the docs match the code."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from kinematics.cli.app import reference_markdown

ROOT = Path(__file__).resolve().parent.parent


def readme_test_command() -> str:
    text = (ROOT / "README.md").read_text()
    block = re.search(r"<!-- test-command -->\s*```sh\n(.+?)\n```", text, re.S)
    assert block, "README lost its marked test command"
    return block.group(1).strip()


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    commands = [ln for ln in ci if ln.strip() and not ln.startswith("#") and not ln.startswith(("set ", "cd "))]
    assert readme_test_command() in commands


def test_cli_reference_is_current():
    assert (ROOT / "docs" / "cli.md").read_text() == reference_markdown(), (
        "docs/cli.md is stale: run `python -m kinematics.cli --reference > docs/cli.md`"
    )


def test_help_is_instant():
    # `kinematics --help` must not import Pinocchio, NumPy or matplotlib.
    code = ("import sys; from kinematics.cli.app import main\ntry:\n main(['--help'])\nexcept SystemExit: pass\n"
            "print(sorted(m for m in ('pinocchio','numpy','matplotlib','meshcat','dask','numba') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_docs_figures_exist_and_are_generated():
    """Every figure a docs page shows exists, and docs/make_figures.py knows how to draw it."""
    import re

    text = "\n".join(p.read_text() for p in (ROOT / "docs").glob("*.md"))
    shown = set(re.findall(r"\]\(figures/([\w-]+)\.png\)", text))
    assert shown, "the docs show figures"
    script = (ROOT / "docs" / "make_figures.py").read_text()
    for name in shown:
        assert (ROOT / "docs" / "figures" / f"{name}.png").exists(), name
        assert f'"{name}"' in script, f"{name} is not drawn by docs/make_figures.py"


def _pages_with_python() -> list[str]:
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    return [str(p.relative_to(ROOT)) for p in pages if "```python" in p.read_text()]


@pytest.mark.parametrize("page", _pages_with_python())
def test_documented_python_runs(page, tmp_path, monkeypatch):
    """Every ```python block of the README and the docs runs as written, in order, in a fresh folder
    (the getting-started example had rotted once: it read bounds the volume engine no longer has)."""
    blocks = re.findall(r"```python\n(.+?)\n```", (ROOT / page).read_text(), re.S)
    assert blocks, f"{page}: a python fence the pattern does not read"
    monkeypatch.chdir(tmp_path)
    scope: dict[str, object] = {}
    for code in blocks:
        exec(compile(code, page, "exec"), scope)
    if page == "docs/getting-started.md":
        assert (tmp_path / "p2us.html").stat().st_size > 10_000  # the file it says it writes
