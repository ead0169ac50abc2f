"""MkDocs hook (mkdocs.yml `hooks:`): expands `<!-- api PACKAGE -->` in a reference page into one
mkdocstrings block per public module of PACKAGE, found in the source tree at build time, so a
module added, moved or removed changes the reference without editing its page.

`<!-- api PACKAGE -->` documents the package's docstring, then every module and subpackage below it
whose name does not start with `_`; `<!-- api PACKAGE flat -->` only the modules directly in it
(the subpackages have their own pages). Each module shows its public names: its `__all__` if it
has one, else the names without a leading underscore.

It also turns a user-guide link to a repository file outside docs/ (e.g. `../urdf/p2us.urdf`, which
works on the repository's web view) into the file's path in code, when that file exists; a link to a
missing file is left for MkDocs to report.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
MARKER = re.compile(r"^<!-- api ([\w.]+)( flat)? -->$", re.M)
OUTSIDE = re.compile(r"\[([^\]]+)\]\((\.\./[^)#\s]+)\)")


def modules(package: str, flat: bool = False) -> list[str]:
    """Dotted names of the public modules below `package` (a folder under ROOT), sorted."""
    folder = ROOT.joinpath(*package.split("."))
    found = []
    for path in sorted(folder.iterdir()):
        if path.name.startswith(("_", ".")):
            continue
        if path.suffix == ".py":
            found.append(f"{package}.{path.stem}")
        elif path.is_dir() and not flat and any((path / f"__init__.{s}").exists() for s in ("py", "pyi")):
            found.append(f"{package}.{path.name}")
            found.extend(modules(f"{package}.{path.name}"))
    return found


def block(name: str, options: dict[str, Any]) -> str:
    lines = [f"::: {name}", "    options:"]
    lines += [f"      {k}: {str(v).lower() if isinstance(v, bool) else v}" for k, v in options.items()]
    return "\n".join(lines)


def expand(markdown: str) -> str:
    def blocks(m: re.Match[str]) -> str:
        package = m.group(1)
        # the package: its docstring only (its re-exports are documented where they are defined)
        parts = [block(package, {"members": False, "show_root_heading": False})]
        parts += [block(name, {"show_submodules": False}) for name in modules(package, bool(m.group(2)))]
        return "\n\n".join(parts)

    return MARKER.sub(blocks, markdown)


def repository_links(markdown: str, page_dir: Path) -> str:
    def plain(m: re.Match[str]) -> str:
        target = (page_dir / m.group(2)).resolve()
        if not (target.is_relative_to(ROOT) and target.exists()):
            return m.group(0)
        return f"{m.group(1)} (`{target.relative_to(ROOT)}`)"

    return OUTSIDE.sub(plain, markdown)


def on_page_markdown(markdown: str, page: Any, config: Any, **_: Any) -> str:
    page_dir = (Path(config["docs_dir"]) / page.file.src_uri).parent
    return repository_links(expand(markdown), page_dir)
