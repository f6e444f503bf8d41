"""``pillar-xval check SPEC.toml``: tolerance checks for CI (see
:mod:`validation.studies.check`).  Exit 0 when every check passes, 1 when one fails, 2 on a
bad spec."""

from __future__ import annotations

import json
import time
from pathlib import Path

from pillar_xval.outcome import write_atomic

from ._args import (add_engine_arguments, add_output_arguments, check_out, engine_from_args,
                    print_json)


def add_parser(sub) -> None:
    """Register ``check`` on the CLI's subparsers."""
    p = sub.add_parser(
        "check", help="tolerance checks from a spec file, for CI (table, JSON, JUnit XML)",
        description="Run the [[check]] tables of SPEC (a model on a scene against another "
                    "model or a closed form, per quantity, within rtol and its source) on the "
                    "study engine, print a table and exit 1 if any check fails.")
    p.add_argument("spec", type=Path, metavar="SPEC.toml", help="the checks (TOML)")
    add_output_arguments(p, "cases and check.json (default out/check/<spec name>)")
    p.add_argument("--junit-xml", type=Path, default=None, metavar="FILE",
                   help="also write a JUnit XML report (one test case per check)")
    add_engine_arguments(p, "recompute cached cases")
    p.set_defaults(func=run)


def run(args) -> int:
    import sys

    from ..output.report import clear_outputs
    from ..studies.check import (junit_xml, load_spec, report_name, run_checks, spec_path,
                                 table_text)

    spec = spec_path(args.spec)
    if spec != args.spec:
        print(f"check: {args.spec} is not in {Path.cwd()}: reading the toolkit's own {spec}",
              file=sys.stderr)
    specs = load_spec(spec)
    name = report_name(spec) if args.out is None else spec.stem
    out = check_out(args.out or Path("out") / "check" / name)
    if args.junit_xml is not None:
        _check_junit(args.junit_xml)
    clear_outputs(out, ("check.json",), "check")
    start = time.perf_counter()
    with engine_from_args(args, "check") as engine:
        rows = run_checks(specs, out / "cases", engine)
    seconds = time.perf_counter() - start
    failed = [r for r in rows if not r["passed"]]
    doc = {"spec": str(spec), "checks": rows, "passed": len(rows) - len(failed),
           "failed": len(failed)}
    write_atomic(out / "check.json", json.dumps(doc, indent=2, allow_nan=False))
    if args.junit_xml is not None:
        write_atomic(args.junit_xml, junit_xml(rows, name, seconds))
    if args.json:
        print_json(doc)
    else:
        print(table_text(rows))
        print(f"{len(rows) - len(failed)} passed, {len(failed)} failed")
        print(f"written: {out / 'check.json'}"
              + (f", {args.junit_xml}" if args.junit_xml is not None else ""))
    return 1 if failed else 0


def _check_junit(path: Path) -> None:
    """--junit-xml must name a file whose folder can be made, before anything is solved."""
    from pillar_xval.scenes import InputError

    if path.is_dir():
        raise InputError(f"--junit-xml {path}: is a folder, expected a file for the JUnit report")
    if path.exists() and not path.is_file():
        raise InputError(f"--junit-xml {path}: is not a regular file")
    check_out(path.parent, "--junit-xml's folder")
