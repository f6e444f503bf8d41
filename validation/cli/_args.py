"""The CLI vocabulary, shared by every command (and by commands added later: use these).

- scene: ``--scene PRESET|FILE`` and repeatable ``--set table.key=value``
  (:func:`add_scene_arguments`);
- model: ``--model NAME`` (default ``bem``) or ``--models A,B,...`` (:func:`add_model_argument`,
  :func:`add_models_argument`);
- one refinement option per model family, the resolution of a solve or of a ladder's coarsest
  level: ``--elements-per-diameter P`` (bem), ``--cells-per-diameter N`` (bem-fft),
  ``--mesh-size S`` (fem-axisym, fem-3d) (:func:`add_refinement_arguments`); ``--levels N``
  for a ladder (:func:`add_levels_argument`).  An option that no chosen model takes is
  refused (:func:`refuse_inapplicable`): the registry :data:`validation.registry.MODELS` says
  which options a model takes, so a model registered later joins without a change here;
- model options with a few values: ``--cells``, ``--contact``, ``--device``, every option
  with choices that a model declares (:func:`add_choice_arguments`); the values of every model
  option are those the models declare (:func:`validation.registry.option_vocabulary`);
- output: ``--out DIR`` and ``--json`` (:func:`add_output_arguments`, :func:`check_out`,
  :func:`print_json`);
- engine: ``--executor``, ``--workers``, ``--scheduler``, ``--fresh``, ``--threads``
  (:func:`add_engine_arguments`); ``--threads`` alone for a command that solves in its own
  process (:func:`add_threads_argument`);
- outcomes: :func:`not_converged` (exit 1 and its line), :func:`study_status` (a study of many
  cases), :func:`failure_status`.

Numbers are parsed strictly (:func:`integer`, :func:`number`): ``5.5`` is not an integer,
``1_0``, ``nan`` and ``inf`` are not numbers.  Every refusal is one line that names the option
as the user wrote it, the value and the allowed range, with exit status 2 (:class:`Parser`).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
from pathlib import Path

from ._exit import (DEBUG_ENV, EXIT_BAD_INPUT, EXIT_INTERNAL_ERROR, EXIT_NOT_CONVERGED,
                    EXIT_TOOL_FAILURE)
from pillar_xval.scenes import InputError, preset_names
from pillar_xval.threads import MAX_THREADS, THREADS_ENV, cpu_count

from ..engine import add_engine_arguments as _engine_arguments
from ..engine import engine_from_args
from ..registry import family_options, flag, option_vocabulary

__all__ = [
    "DEBUG_ENV", "EXIT_INTERNAL_ERROR", "Parser", "add_choice_arguments",
    "add_engine_arguments", "add_levels_argument", "add_model_argument", "add_threads_argument",
    "add_models_argument", "add_output_arguments", "add_refinement_arguments",
    "add_scene_arguments", "check_out", "engine_from_args", "failure_status", "flag", "integer",
    "not_converged", "number", "one_line", "option_type", "print_json", "refuse_inapplicable",
    "scene_pillars", "study_status",
]

_INTEGER = re.compile(r"[+-]?[0-9]+")
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def one_line(text: str, limit: int = 400) -> str:
    """``text`` on one line (whitespace runs collapsed), at most about ``limit`` characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 20] + " ... (cut)"


def _bounds(lo, hi) -> str:
    """An integer range, written out in full (``:g`` would print 2^32 as 4.29497e+09)."""
    def text(v):
        return str(v) if isinstance(v, int) else f"{v:g}"

    return f">= {text(lo)}" if hi is None else f"[{text(lo)}, {text(hi)}]"


def integer(lo: int | None = None, hi: int | None = None):
    """An argparse type: a plain integer (no sign tricks, no ``_``, no ``5.5``) in [lo, hi]."""
    def parse(text: str) -> int:
        if not _INTEGER.fullmatch(text.strip()) or len(text) > 30:
            raise argparse.ArgumentTypeError(
                f"{text!r}: expected an integer{'' if lo is None else ' ' + _bounds(lo, hi)}")
        value = int(text)
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"{value}: allowed range is {_bounds(lo, hi)}")
        return value

    parse.__name__ = "integer"
    return parse


def number(lo: float | None = None, hi: float | None = None, *, open_lo: bool = False):
    """An argparse type: a finite decimal number in [lo, hi] ((lo, hi] with ``open_lo``)."""
    def parse(text: str) -> float:
        if not _DECIMAL.fullmatch(text.strip()) or len(text) > 40:
            raise argparse.ArgumentTypeError(f"{text!r}: expected a decimal number such as "
                                             "0.5 or 1e-3")
        value = float(text)
        below = lo is not None and (value <= lo if open_lo else value < lo)
        if not math.isfinite(value) or below or (hi is not None and value > hi):
            rng = ("(" if open_lo else "[") + f"{lo:g}, " + ("inf)" if hi is None else f"{hi:g}]")
            raise argparse.ArgumentTypeError(f"{text.strip()}: allowed range is {rng}")
        return value

    parse.__name__ = "number"
    return parse


def positive_numbers(text: str) -> list[float]:
    """A comma-separated list of numbers > 0 (argparse type)."""
    parse = number(0.0, open_lo=True)
    return [parse(v.strip()) for v in text.split(",") if v.strip()]


def option_type(name: str):
    """The strict argparse type of a model option (its spec in
    :func:`validation.registry.option_vocabulary`)."""
    spec = option_vocabulary()[name]
    if spec.kind is int:
        return integer(spec.lo, spec.hi)
    return number(spec.lo, spec.hi)


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``pillar-xval CMD: error: ... (see ... --help)``, and
    an option given twice refused (argparse keeps the last silently), unless it is one that
    repeats by design (``--set``)."""

    def parse_known_args(self, args=None, namespace=None):
        self._refuse_repeats(list(sys.argv[1:] if args is None else args))
        return super().parse_known_args(args, namespace)

    def _refuse_repeats(self, args: list[str]) -> None:
        seen: dict[argparse.Action, str] = {}
        commands = any(isinstance(a, argparse._SubParsersAction) for a in self._actions)
        for token in args:
            if token == "--" or (commands and not token.startswith("-")):
                break  # the rest is the command's (its own parser checks it) or positional
            action = self._option_string_actions.get(token.split("=", 1)[0])
            if action is None or isinstance(action, (argparse._AppendAction,
                                                     argparse._CountAction)):
                continue
            if action in seen:
                self.error(f"{seen[action]} given twice: give it once (argparse would keep "
                           "the last silently)")
            seen[action] = token.split("=", 1)[0]

    def error(self, message: str):
        print(f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)",
              file=sys.stderr)
        raise SystemExit(2)


def add_scene_arguments(parser: argparse.ArgumentParser, required: bool = True,
                        default: str | None = None) -> None:
    parser.add_argument(
        "--scene", required=required, default=default,
        help=f"preset ({', '.join(preset_names())}) or a TOML scene file"
             + (f" (default {default})" if default else ""))
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="TABLE.KEY=VALUE",
        help="override a scene value in file units, e.g. --set pillars.E_Pa=1e9 (repeatable); "
             "--set pillars=none removes the pillars")


def add_model_argument(parser, choices, default: str = "bem", help_text: str = "") -> None:
    """``--model NAME`` (one model; the default is ``bem`` wherever a command takes one)."""
    parser.add_argument("--model", default=default, choices=choices,
                        help=help_text or f"model to run (default {default})")


def _model_list(choices):
    def parse(text: str) -> list[str]:
        names = [n.strip() for n in text.split(",") if n.strip()]
        unknown = [n for n in names if n not in choices]
        if not names or unknown:
            raise argparse.ArgumentTypeError(
                f"{text!r}: expected a comma-separated list of {', '.join(choices)}")
        return list(dict.fromkeys(names))

    parse.__name__ = "model list"
    return parse


def add_models_argument(parser, choices, default_help: str) -> None:
    """``--models A,B,...`` where a command runs several models."""
    parser.add_argument("--models", type=_model_list(list(choices)), default=None,
                        metavar="A,B,...", help=f"models, comma-separated ({default_help})")


def add_refinement_arguments(parser, ladder: bool, families=None,
                             defaults: dict | None = None) -> None:
    """The refinement options of ``families`` (default: every family's).  ``ladder``: each
    sets the coarsest level of a ladder; otherwise the resolution of the one solve.  Their
    defaults are None, so that :func:`refuse_inapplicable` sees which the user gave."""
    what = "the coarsest level; " if ladder else ""
    vocabulary = option_vocabulary()
    for name in families or family_options():
        spec = vocabulary[name]
        default = (defaults or {}).get(name)
        parser.add_argument(
            flag(name), dest=name, type=option_type(name), default=None,
            metavar=spec.metavar,
            help=f"{spec.help}; {what}allowed {spec.allowed()}"
                 + ("" if default is None else
                    f" (default {default if isinstance(default, str) else f'{default:g}'})"))


def add_choice_arguments(parser, names=None) -> None:
    """Model options with a few allowed values (default: every such option a model declares:
    ``--cells``, ``--contact``, ``--device``, ...)."""
    vocabulary = option_vocabulary()
    for name in names or [n for n, spec in vocabulary.items() if spec.choices]:
        spec = vocabulary[name]
        parser.add_argument(flag(name), dest=name, choices=spec.choices, default=None,
                            help=spec.help)


def add_threads_argument(parser) -> None:
    """``--threads N``: the threads the command may use in all (the CLI applies it:
    :func:`pillar_xval.threads.threads_override`)."""
    parser.add_argument("--threads", type=integer(1, MAX_THREADS), default=None, metavar="N",
                        help="threads the command may use in all; a study shares them among "
                             "its workers (default: the CPUs this process may use, "
                             f"{cpu_count()} here, or {THREADS_ENV})")


def add_engine_arguments(parser, fresh_help: str = "recompute cached cases") -> None:
    """The engine's options (:func:`validation.engine.add_engine_arguments`) and
    ``--threads``."""
    _engine_arguments(parser, fresh_help)
    add_threads_argument(parser)


def add_levels_argument(parser, default: int, lo: int, hi: int, what: str) -> None:
    parser.add_argument("--levels", type=integer(lo, hi), default=default, metavar="N",
                        help=f"{what}; allowed [{lo}, {hi}] (default {default})")


def add_output_arguments(parser, out_help: str, json_help: str = "") -> None:
    parser.add_argument("--out", type=Path, default=None, metavar="DIR", help=out_help)
    parser.add_argument("--json", action="store_true",
                        help=json_help or "print exactly one JSON document on stdout (the "
                                          "human-readable table is not printed)")


def refuse_inapplicable(args, models, dests=None) -> None:
    """InputError for every model option the user gave that none of ``models`` takes.

    ``dests`` are the argparse destinations to check (default: every model option); an option
    counts as given when it is not None.  The registry :data:`validation.registry.MODELS` says
    which options each model takes."""
    from ..registry import MODELS

    dests = dests or tuple(option_vocabulary())
    takes = {m: set(MODELS[m].options) for m in models if m in MODELS}
    for dest in dests:
        value = getattr(args, dest, None)
        if value is None or any(dest in t for t in takes.values()):
            continue
        owners = sorted(m for m, entry in MODELS.items() if dest in entry.options)
        chosen = ", ".join(models)
        family = any(MODELS[m].options[dest].family for m in owners)
        raise InputError(
            f"{flag(dest)} {_show(value)}: does not apply to "
            f"{'--model' if len(models) == 1 else '--models'} {chosen}"
            + (f" (it {'refines' if family else 'is an option of'} {', '.join(owners)})"
               if owners else ""))


def pillar_models_type(text: str) -> tuple[str, ...]:
    """argparse's type of ``--pillars`` (compare, figures): hooke, elastic, both or a comma
    list, as a tuple of pillar models in the declaration's order
    (:func:`validation.registry.options.pillar_models`)."""
    from ..registry.options import pillar_models

    try:
        return pillar_models(text)
    except InputError as exc:  # argparse names the option: "argument --pillars: ..."
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--pillars ")) from None


def scene_pillars(given, scene):
    """The pillar model(s) a command runs on ``scene``: ``--pillars`` as given, else the
    scene's default (:func:`validation.registry.default_pillars`: elastic on elastic pillars);
    None on a flat scene where none is given.  The elastic pillar on a flat scene is refused
    (InputError, exit 2) before anything is solved."""
    from ..registry import default_pillars

    if given is None:
        return default_pillars(scene)
    kinds = (given,) if isinstance(given, str) else tuple(given)
    if scene.is_flat and "elastic" in kinds:
        raise InputError(f"--pillars {','.join(kinds)}: the scene is flat, it has no pillars "
                         "to model (leave --pillars out)")
    return given


def _show(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def check_out(out: Path, option: str = "--out") -> Path:
    """Make sure ``out`` can be the report folder before anything is solved: refuse an existing
    file, a folder that cannot be created or one that is not writable (one line, exit 2)."""
    out = Path(out)
    shown = f"{option} {os.fspath(out)}"
    if out.exists() and not out.is_dir():
        raise InputError(f"{shown}: is a file, expected a folder for the report")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{shown}: cannot create the folder ({exc.strerror or exc})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise InputError(f"{shown}: the folder is not writable")
    return out


def not_converged(command: str, what: list[str]) -> int:
    """Print the one line of a run in which something did not converge (``what``: one entry
    per case, naming it and saying why); returns the exit status, 1."""
    shown = "; ".join(what[:3]) + (f"; and {len(what) - 3} more" if len(what) > 3 else "")
    print(f"pillar-xval {command}: not converged: {one_line(shown)}", file=sys.stderr)
    return EXIT_NOT_CONVERGED


def failure_status(error: BaseException) -> int:
    """The exit status of a case's error: 2 for input a model refuses (InputError, ScopeError),
    3 for anything else a case may raise (a tool underneath, memory, arithmetic)."""
    return EXIT_BAD_INPUT if isinstance(error, InputError) else EXIT_TOOL_FAILURE


def study_status(command: str, failed: list[tuple[int, str]], unconverged: list[str]) -> int:
    """Exit status of a study of many cases, with its one line on stderr: the most serious of
    ``failed`` ((exit status, what) per case: :func:`failure_status`), else 1 if a case did not
    converge (``unconverged``: what, per case), else 0."""
    if failed:
        code = max(c for c, _ in failed)
        texts = [t for c, t in failed if c == code]
        shown = "; ".join(texts[:3]) + (f"; and {len(texts) - 3} more" if len(texts) > 3 else "")
        kind = "error" if code == EXIT_BAD_INPUT else "failure"
        print(f"pillar-xval {command}: {kind}: {len(failed)} case(s) failed: {one_line(shown)}",
              file=sys.stderr)
        return code
    return not_converged(command, unconverged) if unconverged else 0


def print_json(doc) -> None:
    """Exactly one JSON document on stdout (no NaN or inf: they are not JSON)."""
    print(json.dumps(doc, indent=2, allow_nan=False, default=str))
