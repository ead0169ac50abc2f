"""The in-memory back end of `Scene`: a meshcat window that records the scene tree instead of
sending it, the viewer's JavaScript to inline in an exported page, and a notebook cell's markup."""

from __future__ import annotations

import os
from typing import Any


class RecordingWindow:
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


def viewer_js() -> str:
    """meshcat's viewer JavaScript (main.min.js), to inline in an exported page."""
    from meshcat.servers.zmqserver import VIEWER_ROOT

    with open(os.path.join(VIEWER_ROOT, "main.min.js"), encoding="utf-8") as f:
        return f.read()


class Embedded:
    """A scene's page for a notebook cell (`Scene.notebook`): shown through `_repr_html_`."""

    def __init__(self, markup: str) -> None:
        self.markup = markup

    def _repr_html_(self) -> str:
        return self.markup

    def __repr__(self) -> str:
        return "<Meshcat scene: shown as HTML in Jupyter>"
