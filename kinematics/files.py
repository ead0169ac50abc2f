"""Files: inputs read with one-line errors; outputs written safely (paths checked before any
work, content written atomically)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from pathlib import Path

OUTPUT_SUFFIXES: dict[str, tuple[str, ...]] = {
    "figure": (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff"),
    "csv": (".csv",),
    "points": (".npy", ".csv", ".txt"),
    "html": (".html", ".htm"),
    "urdf": (".urdf",),
    "poses": (".csv", ".npy"),
    "mesh": (".stl", ".ply", ".glb"),
}
"""The suffixes each kind of output file may have (the writer is chosen by the suffix)."""


def read_text(path: str | os.PathLike[str], error: Callable[[Path, str], Exception] | None = None) -> str:
    """The UTF-8 text of an input file (a loop sidecar, a Gepetto robot.yaml, an obstacle file);
    where it cannot be had, `error(path, reason)` is raised (default `ModelFileError`) with a
    one-line reason: not UTF-8 text, or unreadable."""
    from kinematics.errors import ModelFileError

    p = Path(path)
    fail = ModelFileError if error is None else error
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise fail(p, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise fail(p, f"cannot read ({exc.strerror or exc})") from None


def check_output(path: str, option: str, kind: str) -> None:
    """Refuse an output path before any work is done: its directory must exist and be writable,
    the path must not be a directory, and its suffix must be one `kind` can be written as.
    Raises InvalidInputError naming the CLI `option`."""
    import os

    from kinematics.errors import InvalidInputError

    suffixes = OUTPUT_SUFFIXES[kind]
    ext = os.path.splitext(path)[1].lower()
    if not path or path.endswith(os.sep) or os.path.isdir(path):
        raise InvalidInputError(option, f"{path!r} is a directory; give a file name ({'/'.join(suffixes)})")
    if ext not in suffixes:
        raise InvalidInputError(option, f"{path!r}: unknown suffix {ext or '(none)'!r}; use one of {', '.join(suffixes)}")
    parent = os.path.dirname(path) or "."
    if not os.path.isdir(parent):
        raise InvalidInputError(option, f"{path!r}: directory {parent!r} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InvalidInputError(option, f"{path!r}: directory {parent!r} is not writable")
    import tempfile

    try:  # root passes os.access everywhere; only creating a file says (/proc, /sys, read-only mounts)
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError as exc:
        raise InvalidInputError(option, f"{path!r}: cannot create a file in directory {parent!r} "
                                f"({exc.strerror or exc})") from None


Content = str | bytes | Callable[[str], None]
"""What `write_atomic` writes: text, bytes, or a function that writes a given path."""


def write_atomic(path: str, content: Content, option: str) -> None:
    """Write `content` to `path` through a temporary file beside it and a rename, so no reader
    ever sees a half-written file and nothing is left behind on any failure (an interrupt
    included). `content` is text, bytes, or a function that writes a given path (the temporary
    path keeps the suffix, so suffix-driven writers such as savefig and numpy.save work). An
    OSError becomes an InvalidInputError naming the CLI `option`."""
    write_atomic_files([(path, content)], option)


def write_atomic_files(files: Sequence[tuple[str, Content]], option: str) -> None:
    """Write several files as one (a URDF and its sidecar): every `(path, content)` goes to a
    temporary file beside its target first (as in `write_atomic`), and only when all are complete
    are they renamed over their targets. A failure while writing any of them (a writer raising, a
    full disk, an interrupt) leaves every target as it was and no temporary file behind. A target
    that is a directory is refused before anything is written, the one way a rename in the same
    directory fails after another succeeded. An OSError becomes an InvalidInputError naming `option`."""
    import os
    import secrets

    from kinematics.errors import InvalidInputError

    for path, _ in files:
        if os.path.isdir(path):
            raise InvalidInputError(option, f"cannot write {path}: it is a directory")
    tmps: list[str] = []
    path = ""
    try:
        for path, content in files:
            parent, name = os.path.split(path)
            ext = os.path.splitext(name)[1]
            tmp = os.path.join(parent, f".{name}.{os.getpid()}.{secrets.token_hex(4)}.tmp{ext}")
            tmps.append(tmp)
            if callable(content):
                content(tmp)
            elif isinstance(content, bytes):
                with open(tmp, "xb") as fb:
                    fb.write(content)
            else:
                with open(tmp, "x", encoding="utf-8") as f:
                    f.write(content)
        for (path, _), tmp in zip(files, tmps, strict=True):
            os.replace(tmp, path)
    except BaseException as exc:
        for tmp in tmps:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        if isinstance(exc, OSError):
            raise InvalidInputError(option, f"cannot write {path}: {exc.strerror or exc}") from None
        raise
