"""Sweeps: a grid of scenes x models and their options, run on the engine, into one tidy table.

The spec file (TOML; keys are scene keys in file units, as in a scene file)::

    name = "phi-zeta"                 # optional: names the table files (default: the file's stem)
    scene = "paper-fig3-sparse"       # the base scene: a preset, or a TOML file (a relative path
                                      # is read from the spec's folder)
    set = ["pillars.E_Pa=1.6e7"]      # optional: fixed overrides of the base scene
    on_invalid = "error"              # or "skip": leave out grid points the scene refuses

    [grid]                            # crossed axes: every combination of their values
    "pillars.surface_fraction" = [0.01, 0.03, 0.1]                # a list
    "load.indentation_um" = { log = [0.05, 0.5], num = 4 }        # 4 values, log-spaced
    "lens.radius_mm" = { linear = [1.0, 3.0], num = 3 }           # 1, 2, 3

    [[zip]]                           # a zipped group: its keys vary together (equal lengths);
    "pillars.E_Pa" = [1.6e5, 1.6e6]   # the group is one axis, crossed with the grid and with
    "substrate.E_Pa" = [1.6e5, 1.6e6] # the other groups

    [[models]]                        # one table per model; an option given as a list is
    name = "bem"                      # crossed, like a grid axis
    elements_per_diameter = [7, 11]
    [[models]]
    name = "bem-fft"
    cells_per_diameter = 32

``[grid]`` keys may also be written as dotted bare keys (``pillars.surface_fraction = [...]``)
or as nested tables.  A grid point is the base scene with ``--set key=value`` overrides, so
every rule of scene files holds (``pitch_um`` replaces ``surface_fraction``, ``rigid = true``
replaces ``E_Pa``, ...).  Cases are numbered point by point, then model by model.

Python: build a :class:`Sweep` directly (``Sweep("paper-fig3-sparse", axes=[crossed(...),
zipped(...)], models=[ModelSpec("bem", {...})])``), list its cases with :meth:`Sweep.cases`,
run it with :func:`run_sweep` (returns the table rows) and write the table with
:func:`write_table`.

The table, one row per case: the swept keys, then every other scene parameter (file units,
named as in a scene file: ``pillars.surface_fraction``, ``load.indentation_um``, ...), the
model, its options (``option.<name>``), the load's control (``load_control``: indentation or
force: a ``load.force_uN`` axis sweeps forces, each replacing the base's indentation), the
result quantities in SI with the unit in the name (``indentation_m``, given or solved,
``total_force_N``, ``centre_pressure_Pa``, ``contact_radius_m``, ``real_contact_area_m2``),
``pillars_in_contact``, ``iterations``, ``converged``, ``wall_time_s`` (median of the timed
runs), ``peak_memory_MB``, ``status`` (``ok`` or ``failed: why``) and ``case_key``.  Written
as CSV and as Parquet (typed columns).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import InputError, Scene, apply_overrides, scene_dict

from ...engine import Case, CaseStore, Engine, Outcome
from .grid import (Axis, ModelSpec, Sweep, SweepCase, _override, crossed, linear, log,
                   zipped)

__all__ = ["Axis", "ModelSpec", "Sweep", "SweepCase", "crossed", "estimate_cost",
           "estimate_seconds", "linear", "log", "run_sweep", "run_sweep_cases", "scene_columns",
           "table_rows", "write_table", "zipped"]

# Scene parameters in file units, in the order of a scene file.
SCENE_COLUMNS = ("lens.radius_mm", "lens.E_Pa", "lens.nu", "lens.rigid",
                 "pillars.diameter_um", "pillars.height_um", "pillars.surface_fraction",
                 "pillars.pitch_um", "pillars.E_Pa", "pillars.nu", "pillars.rigid",
                 "substrate.E_Pa", "substrate.nu", "substrate.rigid", "load.indentation_um",
                 "load.force_uN")
RESULT_COLUMNS = ("load_control", "indentation_m", "total_force_N", "centre_pressure_Pa",
                  "contact_radius_m",
                  "real_contact_area_m2", "pillars_in_contact", "floor_force_N",
                  "floor_contact_area_m2", "floor_contact_radius_m", "regime", "iterations",
                  "converged", "wall_time_s", "peak_memory_MB", "status", "case_key")


# --- cost --------------------------------------------------------------------------------
# A case whose model has no measured cost fit (fem-3d, auto), or that its fit cannot size.
UNMEASURED_SECONDS = 1.0


def estimate_seconds(case: Case, data=None) -> float:
    """The predicted wall time (s) of a case: the planner's cost fit of its model, measured
    by ``pillar-xval calibrate`` and carried to this machine (the model's default resolution
    where the case gives none; a force-controlled scene at its estimated indentation, as the
    planner reads it); :data:`UNMEASURED_SECONDS` without a fit.  ``data``: the planner's
    data (default: :func:`validation.planner.plan.default_data`)."""
    from ...planner.plan import default_data, planning_scene
    from ...registry import get_model

    fit = (data or default_data()).costs.get(case.model)
    if fit is None:
        return UNMEASURED_SECONDS
    options = dict(case.options)
    if fit.option and options.get(fit.option) is None:
        options[fit.option] = get_model(case.model).default(fit.option)
    try:
        return fit.predict(planning_scene(case.scene), options)[0]
    except (InputError, ValueError, TypeError):
        return UNMEASURED_SECONDS


# The time of more uncached cases than this is the mean of a seeded sample times their
# number: a cost estimate takes milliseconds a case, a million cases would take an hour.
COST_SAMPLE = 500


def estimate_cost(cases: list[SweepCase], folder: Path | None, workers: int) -> dict:
    """Case count, how many are cached already, and the estimated time of the rest."""
    import random

    from ...planner.plan import default_data

    data = default_data()
    store = CaseStore(folder) if folder is not None else None
    per_model: dict[str, dict] = {}
    todo: dict[str, list] = {}
    for c in cases:
        m = per_model.setdefault(c.case.model, {"cases": 0, "cached": 0, "seconds": 0.0})
        m["cases"] += 1
        if store is not None and store.load(c.case)[0] is not None:
            m["cached"] += 1
        else:
            todo.setdefault(c.case.model, []).append(c.case)
    for model, pending in todo.items():
        sample = pending if len(pending) <= COST_SAMPLE else \
            random.Random(0).sample(pending, COST_SAMPLE)
        mean = sum(estimate_seconds(case, data) * case.repeats for case in sample) / len(sample)
        per_model[model]["seconds"] = mean * len(pending)
        per_model[model]["sampled"] = len(sample) < len(pending)
    total = sum(m["seconds"] for m in per_model.values())
    return {"cases": len(cases), "cached": sum(m["cached"] for m in per_model.values()),
            "cpu_seconds": total, "wall_seconds": total / max(1, workers),
            "workers": workers, "per_model": per_model}


# --- running and the table ------------------------------------------------------------------
def scene_columns(scene: Scene) -> dict:
    """Every scene parameter in file units, named as in a scene file (None where absent)."""
    def mat(prefix, m):
        return {f"{prefix}.E_Pa": None if m.rigid else m.E_Pa, f"{prefix}.nu": m.nu,
                f"{prefix}.rigid": m.rigid}

    out = dict.fromkeys(SCENE_COLUMNS)
    out.update({"lens.radius_mm": scene.lens.radius_m * 1e3, **mat("lens", scene.lens.material),
                **mat("substrate", scene.substrate)})
    if scene.force_N is None:
        out["load.indentation_um"] = scene.indentation_m * 1e6
    else:
        out["load.force_uN"] = scene.force_N * 1e6
    if scene.pillars is not None:
        p = scene.pillars
        out.update({"pillars.diameter_um": p.diameter_m * 1e6,
                    "pillars.height_um": p.height_m * 1e6,
                    "pillars.surface_fraction": p.surface_fraction,
                    "pillars.pitch_um": p.pitch_m * 1e6, **mat("pillars", p.material)})
    return out


def _file_units(sweep: Sweep, point: dict) -> dict:
    """The values as the user wrote them (base file, overrides, point), where given."""
    raw = apply_overrides(scene_dict(sweep.scene),
                          [*sweep.overrides, *(_override(k, v) for k, v in point.items())])
    return {f"{t}.{k}": v for t, table in raw.items() if isinstance(table, dict)
            for k, v in table.items() if f"{t}.{k}" in SCENE_COLUMNS}


def run_sweep_cases(sweep: Sweep, out: Path, *, engine: Engine | None = None,
                    fields: bool = False) -> list[tuple[SweepCase, Outcome]]:
    """Run (or resume, from ``out/cases``) every case; (case, outcome) pairs in table order.
    ``fields`` keeps each result's arrays (pressure maps: ``Outcome.field_arrays``)."""
    import dataclasses

    cases, _ = sweep.cases()
    if fields:
        cases = [dataclasses.replace(c, case=dataclasses.replace(c.case, fields=True))
                 for c in cases]
    own = engine is None
    engine = engine or Engine("serial")
    try:
        outcomes = engine.run([c.case for c in cases], Path(out) / "cases", label="sweep")
    finally:
        if own:
            engine.close()
    return list(zip(cases, outcomes))


def table_rows(sweep: Sweep, pairs: list[tuple[SweepCase, Outcome]]) -> list[dict]:
    """One table row per (case, outcome) (see the module docstring for the columns)."""
    option_names = sorted({k for c, _ in pairs for k in c.case.options})
    rows = []
    for c, o in pairs:
        cols = scene_columns(c.scene)
        cols.update(_file_units(sweep, c.point))
        row = {k: c.point[k] for k in sweep.keys}
        row.update({k: v for k, v in cols.items() if k not in row})
        row["model"] = c.case.model
        row.update({f"option.{k}": c.case.options.get(k) for k in option_names})
        if o.ok:
            r = o.result
            row.update({"load_control": r.load_control, "indentation_m": r.indentation_m,
                        "total_force_N": r.total_force_N,
                        "centre_pressure_Pa": r.centre_pressure_Pa,
                        "contact_radius_m": r.contact_radius_m,
                        "real_contact_area_m2": r.real_contact_area_m2,
                        "pillars_in_contact": r.pillars_in_contact,
                        "floor_force_N": r.floor_force_N,
                        "floor_contact_area_m2": r.floor_contact_area_m2,
                        "floor_contact_radius_m": r.floor_contact_radius_m,
                        "regime": r.regime, "iterations": r.iterations,
                        "converged": bool(r.converged),
                        "wall_time_s": o.timing["wall_time_s"],
                        "peak_memory_MB": o.timing["peak_memory_MB"], "status": "ok"})
        else:
            row.update(dict.fromkeys(RESULT_COLUMNS))
            row["status"] = f"failed: {o.error}"
        row["case_key"] = c.case.key
        rows.append(row)
    return rows


def run_sweep(sweep: Sweep, out: Path, *, engine: Engine | None = None) -> list[dict]:
    """Run (or resume, from ``out/cases``) every case; returns the table's rows."""
    return table_rows(sweep, run_sweep_cases(sweep, out, engine=engine))


def table_columns(rows: list[dict]) -> list[str]:
    return list(rows[0]) if rows else [*SCENE_COLUMNS, "model", *RESULT_COLUMNS]


def write_table(rows: list[dict], out: Path, name: str) -> list[Path]:
    """``<name>.csv`` and ``<name>.parquet`` in ``out`` (atomically); returns their paths."""
    from pillar_xval.outcome import atomic_path

    cols = table_columns(rows)
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(cols)
    for r in rows:
        w.writerow(["" if r.get(c) is None else repr(r[c]) if isinstance(r[c], float)
                    else r[c] for c in cols])
    paths = [write_atomic(Path(out) / f"{name}.csv", buf.getvalue())]
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({c: pa.array([r.get(c) for r in rows]) for c in cols})
    with atomic_path(Path(out) / f"{name}.parquet", suffix=".parquet") as tmp:
        pq.write_table(table, tmp)
    paths.append(Path(out) / f"{name}.parquet")
    return paths
