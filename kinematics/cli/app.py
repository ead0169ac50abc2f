"""The `kinematics` command line. `main(argv)` is the entry point; it returns the exit status.

Exit status: 0 success, 1 a well-formed question whose answer is "no" (an unreachable target),
2 bad input (one line on stderr, never a traceback), 130 interrupted (Ctrl-C), 141 stdout closed
by its reader (`| head`), quietly. Output files are checked before any work and written
atomically. Each command module registers its commands (`register`, listed in `COMMANDS`): its
subparser, arguments and handler; shared argument helpers are in `args`. Heavy imports happen
inside the handlers so that `kinematics --help` stays instant.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, NoReturn

from kinematics.cli import (
    design,
    fk,
    guidance,
    ik,
    info,
    jacobian,
    manipulability,
    mobility,
    singular,
    sweep,
    urdf,
    views,
    workspace,
)
from kinematics.cli.args import EXIT_ERROR, EXIT_OK, Command, Parser, Version, subcommands
from kinematics.errors import KinematicsError

if TYPE_CHECKING:
    from sys import UnraisableHookArgs

EXIT_INTERRUPTED, EXIT_PIPE = 130, 141

COMMANDS: tuple[Callable[[Command], None], ...] = (
    info.register, fk.register, ik.register, jacobian.register, manipulability.register, mobility.register,
    workspace.register, singular.register, sweep.register,
    design.register,  # usable-workspace, dexterity, synthesize, workspace-mesh
    guidance.register, views.register, urdf.register,
)
"""Each command module's `register(command)`, which adds its commands (subparser, arguments,
handler), in the order of the help. The modules import nothing heavy at module level."""

OUTPUTS = {"plot": ("--plot", "figure"), "output": ("-o/--output", "urdf"), "export": ("--export", "html"),
           "points": ("--points", "points"), "out": ("--out", "csv"), "csv": ("--csv", "csv")}
"""Output options (argparse dest -> option, kind of file), checked before a command runs."""
OUTPUTS_BY_COMMAND = {("fk", "out"): ("--out", "poses")}
"""Where one command's option writes another kind of file than OUTPUTS says."""


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (exposed for the CLI-reference check in the tests)."""
    parser = Parser(
        prog="kinematics",
        description="Kinematic analysis of serial and parallel robots described by URDF (built on Pinocchio).",
        epilog="Units are SI (m, rad, s, N). Exit status: 0 ok, 1 unreachable target, 2 bad input, "
               "130 interrupted, 141 output pipe closed.",
    )
    parser.add_argument("--version", action=Version, help="print the version and exit")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)

    command = subcommands(sub)
    for register in COMMANDS:
        register(command)
    return parser


def reference_markdown() -> str:
    """The CLI reference (docs/cli.md): every command's --help, at a fixed width of 100 columns."""
    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        parser = build_parser()
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parts = [
            "# CLI reference",
            "",
            "Generated from the parser by `python -m kinematics.cli --reference > docs/cli.md`; a test",
            "fails if this page and `kinematics COMMAND --help` disagree.",
            "",
            "```text",
            parser.format_help().rstrip(),
            "```",
        ]
        for name, p in sub.choices.items():
            parts += ["", f"## `kinematics {name}`", "", "```text", p.format_help().rstrip(), "```"]
        return "\n".join(parts) + "\n"
    finally:
        if saved is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = saved


def _check_outputs(args: argparse.Namespace) -> None:
    from kinematics.files import check_output

    for dest, default in OUTPUTS.items():
        path = getattr(args, dest, None)
        if path is not None:
            option, kind = OUTPUTS_BY_COMMAND.get((args.command, dest), default)
            check_output(path, option, kind)


def _run(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a one-line usage error already printed
        return exc.code if isinstance(exc.code, int) else EXIT_ERROR
    if args.command is None:
        parser.print_help()
        return EXIT_OK
    import warnings

    from kinematics.errors import KinematicsWarning

    def show(message: Warning | str, category: type[Warning], *rest: object, **kw: object) -> None:
        if issubclass(category, KinematicsWarning):  # one line, like the errors
            print(f"kinematics {args.command}: warning: {message}", file=sys.stderr)
        else:
            default_show(message, category, *rest, **kw)  # type: ignore[arg-type]

    try:
        with warnings.catch_warnings():
            # an overflow or invalid operation the inputs provoked is bad input, not a result
            warnings.simplefilter("error", RuntimeWarning)
            warnings.simplefilter("default", KinematicsWarning)
            default_show, warnings.showwarning = warnings.showwarning, show
            _check_outputs(args)
            return int(args.func(args))
    except KinematicsError as exc:
        print(f"kinematics {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except RuntimeWarning as exc:
        print(f"kinematics {args.command}: error: the inputs are out of a computable range ({exc})", file=sys.stderr)
        return EXIT_ERROR


class _CtrlC:
    """Ctrl-C as one line and exit 130, wherever it lands.

    Python raises KeyboardInterrupt in whatever Python code runs when the signal arrives. Two
    places hide it: a compiled Numba kernel calling back into Python returns it wrapped in
    SystemErrors, and a C library's callback into Python (LLVM's object cache, while Numba
    compiles) swallows it, reports it as "Exception ignored", and either carries on as if nothing
    happened or fails later with an unrelated error. So the handler remembers the press (any error
    after it is the interrupt's doing), and a swallowed one is delivered again 50 ms later, once
    the callback has returned. Installed only where Python's own handler is (the main thread, SIGINT
    not ignored), and restored on the way out.
    """

    def __init__(self) -> None:
        self.pressed = False
        self.stopping = False  # set once the command is ending: a late Ctrl-C has nothing to stop
        self._installed = False
        self._timer: threading.Timer | None = None

    def __enter__(self) -> _CtrlC:
        if (threading.current_thread() is threading.main_thread()
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler):
            self._handler = signal.signal(signal.SIGINT, self._press)
            self._hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
            self._installed = True
        return self

    def __exit__(self, *exc: object) -> None:
        self.stopping = True
        if self._timer is not None:
            self._timer.cancel()
        if self._installed:
            sys.unraisablehook = self._hook
            signal.signal(signal.SIGINT, self._handler)

    def _press(self, signum: int, frame: object) -> None:
        self.pressed = True
        if not self.stopping:
            raise KeyboardInterrupt

    def _unraisable(self, info: UnraisableHookArgs) -> None:
        if issubclass(info.exc_type, KeyboardInterrupt):
            if self._timer is None or not self._timer.is_alive():
                self._timer = threading.Timer(0.05, os.kill, (os.getpid(), signal.SIGINT))
                self._timer.daemon = True
                self._timer.start()
        elif not self.pressed:  # after a press, errors like this are the fallout of the interrupt
            self._hook(info)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 ok, 1 unreachable, 2 bad input, 130 interrupted,
    141 stdout closed early)."""
    with _CtrlC() as ctrl_c:
        try:
            code = _run(argv)
            sys.stdout.flush()
            return code
        except SystemExit:
            raise
        except BaseException as exc:
            ctrl_c.stopping = True
            if not (ctrl_c.pressed or isinstance(exc, KeyboardInterrupt)):
                lost = _lost_stdout(exc) if isinstance(exc, OSError) else None
                if lost is None:
                    raise
                return lost
            print("kinematics: interrupted", file=sys.stderr)
            _INTERRUPTED.append(exc)
            return EXIT_INTERRUPTED


_INTERRUPTED: list[BaseException] = []
"""The interrupts `main` reported, kept: freeing their tracebacks frees what the interrupted work
left half-built, and LLVM's modules from an interrupted Numba compilation can crash the process
when freed (a segfault in llvmlite's module disposal, twice in about 70 interrupts of
compilation). `run` then exits without freeing anything."""


def run() -> NoReturn:
    """The process entry point (`kinematics`, `python -m kinematics`): `main`'s status as the exit
    status; after an interrupt, with the streams flushed and nothing else torn down (`_INTERRUPTED`;
    the coal pool's workers and Dask's stop on their own, the viewer's server in its command)."""
    code = main()
    if code == EXIT_INTERRUPTED:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):  # a reader gone meanwhile (`| head`)
                stream.flush()
        os._exit(code)
    sys.exit(code)


def _lost_stdout(exc: OSError) -> int | None:
    """The exit status when `exc` says stdout is gone (its reader closed the pipe) or full; None for
    any other OSError."""
    import errno

    if not isinstance(exc, BrokenPipeError) and exc.errno != errno.ENOSPC and exc.errno != errno.EIO:
        return None
    # send what is left to /dev/null so the interpreter's final flush is quiet too
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # pragma: no cover - stdout without a descriptor
        pass
    if isinstance(exc, BrokenPipeError):
        return EXIT_PIPE
    print(f"kinematics: error: cannot write the report to stdout: {exc.strerror or exc}", file=sys.stderr)
    return EXIT_ERROR
