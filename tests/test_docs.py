"""The documentation site builds: `mkdocs build --strict` (warnings are errors) of the user guide and
the API reference generated from the docstrings, offline.

A docstring the Google-style parser cannot read (an argument the signature does not have, a
section it cannot split), a broken cross-reference, a user-guide link to a missing page or anchor,
or a page left out of the nav is a warning, so the build fails. The build runs in a subprocess
whose sockets cannot connect, so a configuration that fetches anything (a remote inventory, a
theme asset) fails too.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

# Loaded by the build's interpreter before anything else (via PYTHONPATH): every socket that tries
# to reach another host raises, so the build is offline by construction, not by luck.
OFFLINE = """
import socket

def _refuse(self, address, *args, **kwargs):
    if self.family != socket.AF_UNIX:
        raise OSError(f"tests/test_docs.py: the docs build must stay offline (it tried {address!r})")
    return _connect(self, address, *args, **kwargs)

_connect = socket.socket.connect
socket.socket.connect = _refuse
socket.socket.connect_ex = _refuse
"""


def build(tmp_path: Path, config: Path = ROOT / "mkdocs.yml") -> subprocess.CompletedProcess[str]:
    (tmp_path / "offline").mkdir()
    (tmp_path / "offline" / "sitecustomize.py").write_text(OFFLINE)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path / "offline"), str(ROOT)])}
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(config),
                           "--site-dir", str(tmp_path / "site")], cwd=ROOT, env=env, capture_output=True, text=True)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("docs")
    run = build(tmp)
    warnings = [ln for ln in run.stderr.splitlines() if "WARNING" in ln or "ERROR" in ln]
    assert run.returncode == 0, "\n".join(warnings) or run.stderr[-3000:]
    return tmp / "site"


def test_the_site_builds_strictly_offline(site):
    assert (site / "index.html").exists()
    assert (site / "benchmarks" / "index.html").exists()


@pytest.mark.parametrize("package", ["model", "generic", "mechanisms", "analyses", "guidance", "views"])
def test_every_public_module_has_its_reference(site, package):
    """Each package's page documents every public module below it (found in the tree, not listed)."""
    root = importlib.import_module(f"kinematics.{package}")
    found = [m.name for m in pkgutil.walk_packages(root.__path__, f"{root.__name__}.")
             if not re.search(r"\._", m.name)]
    assert len(found) >= 2, found
    html = (site / "reference" / package / "index.html").read_text()
    anchors = set(re.findall(r'id="(kinematics\.[\w.]+)"', html))
    assert sorted(set(found) - anchors) == []
    # the public names are documented (with their docstrings), private ones are not
    assert any(a.count(".") > m.count(".") for a in anchors for m in found if a.startswith(m + "."))
    assert not [a for a in anchors if re.search(r"\._[a-z]", a)]


def test_every_docstring_section_was_parsed(site):
    """A section header the Google parser did not take (e.g. `Returns:` right under the arguments
    without a blank line) is left as a paragraph: "Returns:" on a line of its own in the page."""
    unparsed = [f"{page.parent.name}: {m.group(0)[:80]!r}" for page in sorted((site / "reference").glob("*/index.html"))
                for m in re.finditer(r"<p>(Args|Arguments|Returns|Raises|Yields|Attributes|Examples?):\s*\n[^<]*",
                                     page.read_text())]
    assert unparsed == []


def test_the_mechanism_interface_is_documented(site):
    html = (site / "reference" / "mechanisms" / "index.html").read_text()
    assert 'id="kinematics.mechanisms.base.Mechanism"' in html
    assert "doc-section-title" in html or "Parameters" in html  # docstring sections were parsed


def test_a_broken_docstring_fails_the_build(tmp_path):
    """The check itself can fail: a docstring naming an argument its function lacks, a cross-reference
    to nothing, and a user-guide link to a missing page are each reported, and the build stops."""
    pkg = tmp_path / "src" / "broken"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text('"""A package."""\n')
    (pkg / "mod.py").write_text('def f(x: float) -> float:\n    """Twice x.\n\n    Args:\n'
                                '        y: not an argument of f.\n    """\n    return 2 * x\n\n\n'
                                'def g() -> None:\n    """Calls [f][broken.mod.nothing]."""\n')
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "index.md").write_text("# broken\n\nSee [the guide](guide.md).\n\n::: broken.mod\n")
    text = (ROOT / "mkdocs.yml").read_text()
    plugins = text[text.index("plugins:"):text.index("nav:")].replace("paths: [.]", f"paths: [{tmp_path / 'src'}]")
    config = tmp_path / "mkdocs.yml"
    config.write_text(f"site_name: broken\ndocs_dir: {tmp_path / 'docs'}\nstrict: true\n{plugins}")
    run = build(tmp_path, config)
    assert run.returncode != 0
    assert "Parameter 'y' does not appear in the function signature" in run.stderr
    assert "Could not find cross-reference target 'broken.mod.nothing'" in run.stderr
    assert "'guide.md'" in run.stderr
