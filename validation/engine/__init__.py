"""The study engine: cases, their keys and records, executors, progress.

A :class:`Case` is (scene, model, options) -> :class:`pillar_xval.outcome.ContactResult`.  An
:class:`Engine` runs a list of cases into a folder (:class:`CaseStore`): each finished case is
written at once, atomically, and skipped on a rerun; a corrupt or inconsistent record is
recomputed; a case another process is computing is waited for, never duplicated.  Cases run
serially, on a local process pool or on a Dask cluster.  See :mod:`._case` for how the code
version enters the key.

Example
-------
>>> from pillar_xval.scenes import load_scene
>>> from validation.engine import Case, Engine
>>> cases = [Case("bem", load_scene("hertz"), {"elements_per_diameter": p}) for p in (5, 7)]
>>> with Engine("pool", workers=2) as engine:                      # doctest: +SKIP
...     outcomes = engine.run(cases, "out/my-study/cases")
"""

from ._case import (COMPUTING_PACKAGES, Case, accepts_vtu, canonical_json,
                    case_key, code_digest, code_version, compute_case, model_code,
                    package_root, scene_physics, source_digest)
from ._engine import CASE_ERRORS, Engine, Outcome
from ._executors import EXECUTORS, default_workers, make_executor
from ._progress import Progress, SolveProgress
from ._store import RTOL_FORCE_SUM, CaseStore, read_journal

__all__ = [
    "CASE_ERRORS",
    "COMPUTING_PACKAGES",
    "EXECUTORS",
    "RTOL_FORCE_SUM",
    "Case",
    "CaseStore",
    "Engine",
    "Outcome",
    "Progress",
    "SolveProgress",
    "accepts_vtu",
    "add_engine_arguments",
    "canonical_json",
    "case_key",
    "code_digest",
    "code_version",
    "compute_case",
    "default_workers",
    "engine_from_args",
    "make_executor",
    "read_journal",
    "model_code",
    "package_root",
    "scene_physics",
    "source_digest",
]


def add_engine_arguments(parser, fresh_help: str = "recompute cached cases") -> None:
    """The engine options every study command takes."""
    g = parser.add_argument_group("engine")
    g.add_argument("--executor", choices=EXECUTORS, default=None,
                   help="where cases run: serial (this process), pool (local processes, the "
                        "default) or dask (--scheduler ADDRESS, or a local cluster)")
    g.add_argument("--workers", type=int, default=None, metavar="N",
                   help="pool or local Dask processes (default: one per thread the command "
                        "may use, see --threads; the threads are shared among them)")
    g.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="a running Dask scheduler to send the cases to (implies "
                        "--executor dask)")
    g.add_argument("--fresh", action="store_true", help=fresh_help)


def engine_from_args(args, label: str = "") -> Engine:
    """An :class:`Engine` from the options of :func:`add_engine_arguments`."""
    return Engine(args.executor, args.workers, args.scheduler, fresh=args.fresh, label=label)
