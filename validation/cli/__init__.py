"""Command line: ``pillar-xval COMMAND --scene PRESET|FILE [--set table.key=value ...]``.

Each command lives in its own module of this package, listed in ``COMMANDS``: a thin layer
that parses options (the shared vocabulary of :mod:`validation.cli._args`), validates every
option before anything is solved, calls a study (:mod:`validation.studies`) and prints.  A
module provides ``add_parser(subparsers)`` (which sets ``func``) and the function it names.

Exit status and stderr (the failure policy of :mod:`pillar_xval.scenes._errors`): every outcome is one
line on stderr, never a traceback.

====  ===========================================================================
0     done
1     a solver did not converge (the line says which case and why)
2     bad input or a scene outside a model's scope (option or key as written, value, range)
3     a tool underneath failed: gmsh, a linear solver, the file system, memory
4     an internal error, i.e. a bug: ``--debug`` (or ``PILLAR_XVAL_DEBUG=1``) shows its
      traceback
130   interrupted (Ctrl-C)
143   terminated (SIGTERM): one line, and the finished cases of a study stay on disk
====  ===========================================================================

A signal ends a command at once, also inside a library call that runs for minutes (gmsh,
PARDISO): :mod:`._signals`.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import warnings

# Only the standard library and the exit statuses at import: the toolkit (numpy, scipy, the
# registry) is loaded inside main(), where a failure to load it (out of memory under a tight
# `ulimit -v`: "failed to map segment", MemoryError) is one line and exit 3, not a traceback
# from the console script's own import.
from ._exit import DEBUG_ENV, EXIT_BAD_INPUT, EXIT_INTERNAL_ERROR, EXIT_TOOL_FAILURE
from ._signals import Terminated, Watchdog, final_line

__all__ = ["COMMANDS", "DEBUG_ENV", "EXIT_INTERNAL_ERROR", "add_scene_arguments",
           "build_parser", "main"]

COMMANDS = ("validation.cli.solve", "validation.cli.compare", "validation.cli.converge",
            "validation.cli.gecit", "validation.cli.tradeoff", "validation.cli.sweep",
            "validation.cli.figures", "validation.cli.lattice", "validation.cli.plan",
            "validation.cli.calibrate", "validation.cli.extremes", "validation.cli.check",
            "validation.cli.regimes", "validation.cli.curve", "validation.cli.onset",
            "validation.cli.floor_check")


_LAZY = ("Parser", "add_scene_arguments", "one_line")


def __getattr__(name: str):
    """The shared vocabulary's names, loaded on first use (see the imports above)."""
    if name in _LAZY:
        from . import _args

        return getattr(_args, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def build_parser() -> argparse.ArgumentParser:
    from pillar_xval.outcome import package_version

    from ._args import Parser

    parser = Parser(
        prog="pillar-xval",
        description="Contact of a spherical lens on a hexagonal lattice of pillars: "
                    "boundary-element solvers cross-validated against finite elements.  SI "
                    "units in results; scene files state theirs in the key names.",
        epilog="Exit status: 0 done, 1 not converged, 2 bad input, 3 a tool failed "
               f"(gmsh, a linear solver, files, memory), {EXIT_INTERNAL_ERROR} internal error "
               "(--debug shows the traceback), 130 interrupted, 143 terminated.")
    parser.add_argument("--version", action="version",
                        version=f"pillar-xval {package_version()}")
    parser.add_argument("--debug", action="store_true",
                        help=f"show the traceback of an internal error (or set {DEBUG_ENV}=1)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                parser_class=Parser)
    for name in COMMANDS:
        importlib.import_module(name).add_parser(sub)
    for command in sub.choices.values():
        # SUPPRESS: a subcommand's default must not overwrite `pillar-xval --debug CMD`.
        command.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                             help="show the traceback of an internal error")
    return parser


def _debugging(args) -> bool:
    return bool(getattr(args, "debug", False)) or os.environ.get(DEBUG_ENV, "") not in ("", "0")


def _one_line_warnings(prog: str):
    """Warnings as one line without a source path (``--debug`` keeps Python's own form)."""
    from ._args import one_line

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{prog}: warning: {category.__name__}: {one_line(message, 400)}",
              file=file or sys.stderr)

    return show


def main(argv: list[str] | None = None) -> int:
    """Run one command; returns the exit status (see the module docstring)."""
    if sys.stdout is None:  # started with stdout closed: every printed result would be lost
        print("pillar-xval: error: standard output is closed; redirect it to a file or "
              "/dev/null", file=sys.stderr or sys.__stderr__)
        return EXIT_BAD_INPUT
    if (sys.argv[1:] if argv is None else argv) == ["--version"]:
        # The version needs neither the toolkit nor the parser (0.1 s, not 0.5).
        from pillar_xval._version import package_version

        print(f"pillar-xval {package_version()}")
        return 0
    watchdog = Watchdog()
    errors = _tolerant(sys.stdout)
    try:
        try:
            _load()
        # A C extension that runs out of memory while it loads can also leave a SystemError.
        except (ImportError, MemoryError, SystemError) as exc:
            if os.environ.get(DEBUG_ENV, "") not in ("", "0") or "--debug" in (
                    argv if argv is not None else sys.argv[1:]):
                raise
            print(f"pillar-xval: failure: {_load_failure(exc)}", file=sys.stderr)
            return EXIT_TOOL_FAILURE
        return _main(argv, watchdog)
    except KeyboardInterrupt as exc:  # before a command ran (loading the toolkit)
        signum = signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT
        status, line = final_line("pillar-xval", signum)
        print(line, file=sys.stderr)
        return status
    finally:
        watchdog.stop()
        _tolerant(sys.stdout, errors)


def _load() -> None:
    """Load the toolkit the commands need (the shared vocabulary, the scenes, the command
    modules): the first place a tight memory limit bites."""
    importlib.import_module("pillar_xval.scenes")
    importlib.import_module("validation.cli._args")
    for name in COMMANDS:
        importlib.import_module(name)


def _load_failure(exc: BaseException) -> str:
    """One line for a library that could not be loaded: out of memory (a tight `ulimit -v`
    makes the loader fail to map a shared object) or missing."""
    text = " ".join(str(exc).split())
    text = text if len(text) <= 200 else text[:197] + "..."
    if isinstance(exc, (MemoryError, SystemError)) or "map segment" in text \
            or "allocate memory" in text:
        detail = text or "no detail"
        return (f"out of memory loading the libraries ({type(exc).__name__}: {detail}); "
                "raise the process's memory limit (ulimit -v)")
    return f"cannot load a library ({type(exc).__name__}: {text}); is the toolkit installed?"


def _tolerant(stream, errors: str = "backslashreplace") -> str | None:
    """Let ``stream`` write what its encoding cannot (a path in Φ or ü under
    PYTHONIOENCODING=ascii or a non-UTF-8 locale) as backslash escapes, as stderr does,
    instead of failing after the work is done; returns its previous setting."""
    before = getattr(stream, "errors", None)
    if errors is not None and before is not None and hasattr(stream, "reconfigure"):
        try:
            stream.reconfigure(errors=errors)
        except (ValueError, OSError, AttributeError):  # a stream that cannot: leave it
            return None
    return before


def _main(argv: list[str] | None, watchdog: Watchdog) -> int:
    from pillar_xval.scenes import InputError, ToolError

    from ._args import one_line

    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a one-line usage error (status 2)
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    from pillar_xval.threads import threads_override

    prog = f"pillar-xval {args.command}"
    watchdog.prog = prog
    debug = _debugging(args)
    with warnings.catch_warnings():
        if not debug:
            warnings.showwarning = _one_line_warnings(prog)
        try:
            with threads_override(getattr(args, "threads", None)):
                return int(args.func(args) or 0)
        except KeyboardInterrupt as exc:  # Terminated (SIGTERM) too
            status, line = final_line(prog, signal.SIGTERM if isinstance(exc, Terminated)
                                      else signal.SIGINT)
            print(line, file=sys.stderr)
            return status
        except InputError as exc:  # SceneError, ScopeError too
            print(f"{prog}: error: {one_line(exc)}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except ToolError as exc:
            print(f"{prog}: failure: {one_line(exc)}", file=sys.stderr)
            return EXIT_TOOL_FAILURE
        except MemoryError as exc:
            detail = f" ({one_line(exc, 200)})" if str(exc) else ""
            print(f"{prog}: failure: out of memory{detail}; try a coarser resolution or a "
                  "smaller scene", file=sys.stderr)
            return EXIT_TOOL_FAILURE
        except OSError as exc:
            print(f"{prog}: failure: file system: {one_line(exc)}", file=sys.stderr)
            return EXIT_TOOL_FAILURE
        except ImportError as exc:  # a library a command loads late (memory, or missing)
            if debug:
                raise
            print(f"{prog}: failure: {_load_failure(exc)}", file=sys.stderr)
            return EXIT_TOOL_FAILURE
        except Exception as exc:
            if debug:
                raise
            print(f"{prog}: internal error: {type(exc).__name__}: {one_line(exc, 200)} (a bug; "
                  f"--debug or {DEBUG_ENV}=1 shows the traceback)", file=sys.stderr)
            return EXIT_INTERNAL_ERROR


if __name__ == "__main__":
    sys.exit(main())
