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
model, its options (``option.<name>``), the result quantities in SI with the unit in the name
(``total_force_N``, ``centre_pressure_Pa``, ``contact_radius_m``, ``real_contact_area_m2``),
``pillars_in_contact``, ``iterations``, ``converged``, ``wall_time_s`` (median of the timed
runs), ``peak_memory_MB``, ``status`` (``ok`` or ``failed: why``) and ``case_key``.  Written
as CSV and as Parquet (typed columns).
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from scenes import InputError, Scene, SceneError, apply_overrides, load_scene, scene_dict, \
    scene_from_dict, write_atomic

from ..engine import Case, CaseStore, Engine

# Scene parameters in file units, in the order of a scene file.
SCENE_COLUMNS = ("lens.radius_mm", "lens.E_Pa", "lens.nu", "lens.rigid",
                 "pillars.diameter_um", "pillars.height_um", "pillars.surface_fraction",
                 "pillars.pitch_um", "pillars.E_Pa", "pillars.nu", "pillars.rigid",
                 "substrate.E_Pa", "substrate.nu", "substrate.rigid", "load.indentation_um")
RESULT_COLUMNS = ("total_force_N", "centre_pressure_Pa", "contact_radius_m",
                  "real_contact_area_m2", "pillars_in_contact", "iterations", "converged",
                  "wall_time_s", "peak_memory_MB", "status", "case_key")
_RANGE_KEYS = {"linear", "log", "num"}


# --- values ------------------------------------------------------------------------------
def linear(start: float, stop: float, num: int) -> list[float]:
    """``num`` values from ``start`` to ``stop``, evenly spaced, both ends included."""
    _check_range("linear", start, stop, num)
    if num == 1:
        return [float(start)]
    return [start + (stop - start) * i / (num - 1) for i in range(num)]


def log(start: float, stop: float, num: int) -> list[float]:
    """``num`` values from ``start`` to ``stop``, evenly spaced in log, both ends included."""
    _check_range("log", start, stop, num)
    if start <= 0 or stop <= 0:
        raise InputError(f"log = [{start}, {stop}]: both ends must be > 0")
    if num == 1:
        return [float(start)]
    ratio = math.log(stop / start) / (num - 1)
    return [start * math.exp(ratio * i) for i in range(num - 1)] + [float(stop)]


def _check_range(kind, start, stop, num) -> None:
    if not isinstance(num, int) or isinstance(num, bool) or num < 1:
        raise InputError(f"{kind} range: num = {num!r}: must be an integer >= 1")
    for v in (start, stop):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputError(f"{kind} = [{start}, {stop}]: ends must be finite numbers")


def _values(key: str, spec) -> list:
    """A list, or a range table ``{linear|log = [start, stop], num = N}``."""
    if isinstance(spec, list):
        if not spec:
            raise InputError(f"{key} = []: give at least one value")
        return list(spec)
    if isinstance(spec, dict) and set(spec) <= _RANGE_KEYS and "num" in spec:
        kinds = [k for k in ("linear", "log") if k in spec]
        if len(kinds) != 1 or not isinstance(spec[kinds[0]], list) or len(spec[kinds[0]]) != 2:
            raise InputError(f"{key} = {spec}: expected {{linear = [start, stop], num = N}} "
                             "or {log = [start, stop], num = N}")
        fn = linear if kinds[0] == "linear" else log
        return fn(*spec[kinds[0]], spec["num"])
    return [spec]  # a single value: a fixed key of the grid


# --- the grid ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Axis:
    """One axis of the grid: one or more scene keys whose values vary together."""

    values: dict

    def __post_init__(self):
        lengths = {k: len(v) for k, v in self.values.items()}
        if not lengths:
            raise InputError("an axis needs at least one key")
        if len(set(lengths.values())) != 1:
            raise InputError(f"zipped keys need equal lengths; got {lengths}")

    def __len__(self) -> int:
        return len(next(iter(self.values.values())))

    def point(self, i: int) -> dict:
        return {k: v[i] for k, v in self.values.items()}


def crossed(key: str, values) -> Axis:
    """An axis of one key (``values``: a list or a range from :func:`linear`/:func:`log`)."""
    return Axis({key: list(values)})


def zipped(values: dict) -> Axis:
    """An axis of several keys varying together: ``{key: [v0, v1, ...], ...}``."""
    return Axis({k: list(v) for k, v in values.items()})


@dataclass(frozen=True)
class ModelSpec:
    """A model and its options; an option whose value is a list is crossed."""

    name: str
    options: dict = field(default_factory=dict)

    def option_sets(self) -> list[dict]:
        keys = sorted(self.options)
        lists = [v if isinstance(v, list) else [v] for v in (self.options[k] for k in keys)]
        return [dict(zip(keys, combo)) for combo in itertools.product(*lists)]


@dataclass(frozen=True)
class SweepCase:
    """One row of the table: the grid point (file units), its scene and the engine case."""

    point: dict
    scene: Scene
    case: Case


def _override(key: str, value) -> str:
    if isinstance(value, bool):
        return f"{key}={'true' if value else 'false'}"
    return f"{key}={value!r}"


@dataclass(frozen=True)
class Sweep:
    """A base scene, the axes of its grid (crossed with each other) and the models."""

    scene: str
    axes: tuple = ()
    models: tuple = ()
    overrides: tuple = ()
    name: str = "sweep"
    on_invalid: str = "error"

    def __post_init__(self):
        if not self.models:
            raise InputError("a sweep needs at least one [[models]] table")
        if self.on_invalid not in ("error", "skip"):
            raise InputError(f"on_invalid = {self.on_invalid!r}: allowed: error, skip")
        keys = [k for a in self.axes for k in a.values]
        repeated = sorted({k for k in keys if keys.count(k) > 1})
        if repeated:
            raise InputError(f"sweep keys given twice: {', '.join(repeated)}")

    @property
    def keys(self) -> list[str]:
        return [k for a in self.axes for k in a.values]

    def points(self) -> list[dict]:
        """Every grid point, the first axis varying slowest."""
        out = []
        for idx in itertools.product(*(range(len(a)) for a in self.axes)):
            point = {}
            for a, i in zip(self.axes, idx):
                point.update(a.point(i))
            out.append(point)
        return out

    def cases(self) -> tuple[list[SweepCase], list[tuple[dict, str]]]:
        """(cases, skipped points with the reason).  A point the scene refuses raises an
        InputError naming the point, unless ``on_invalid = "skip"``."""
        from ..models import MODELS, model_names

        for m in self.models:
            if m.name not in MODELS:
                raise InputError(f"[[models]] name = {m.name!r}: unknown; available: "
                                 f"{', '.join(model_names())}")
            bad = sorted(set(m.options) - set(MODELS[m.name][2]) - {"vtu_path"})
            if bad or "vtu_path" in m.options:
                raise InputError(f"[[models]] {m.name}: unknown option(s) "
                                 f"{', '.join(bad or ['vtu_path'])}; allowed: "
                                 f"{', '.join(o for o in MODELS[m.name][2] if o != 'vtu_path')}")
        out, skipped = [], []
        for point in self.points():
            sets = [*self.overrides, *(_override(k, v) for k, v in point.items())]
            try:
                scene = load_scene(self.scene, sets)
            except SceneError as exc:
                if self.on_invalid == "skip":
                    skipped.append((point, str(exc)))
                    continue
                raise SceneError(f"sweep point {_describe(point)}: {exc}") from None
            for m in self.models:
                for opts in m.option_sets():
                    out.append(SweepCase(point, scene, Case(m.name, scene, opts,
                                                            tag=_describe(point))))
        return out, skipped

    # --- files ---
    @classmethod
    def from_toml(cls, path: str | Path) -> "Sweep":
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text())
        except FileNotFoundError:
            raise InputError(f"sweep spec {str(path)!r}: no such file") from None
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"sweep spec {path}: not valid TOML ({exc})") from None
        return cls.from_dict(data, base_dir=path.parent, default_name=path.stem)

    @classmethod
    def from_dict(cls, data: dict, base_dir: Path = Path("."),
                  default_name: str = "sweep") -> "Sweep":
        allowed = {"name", "description", "scene", "set", "on_invalid", "grid", "zip", "models"}
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise InputError(f"sweep spec: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
        if "scene" not in data:
            raise InputError("sweep spec: 'scene' (a preset or a scene file) is missing")
        scene = str(data["scene"])
        if not _is_preset(scene) and not Path(scene).is_absolute():
            scene = str(Path(base_dir) / scene)
        overrides = data.get("set", [])
        if not isinstance(overrides, list) or not all(isinstance(s, str) for s in overrides):
            raise InputError("sweep spec: 'set' must be a list of \"table.key=value\" strings")
        axes = [Axis({k: _values(k, v)}) for k, v in _flatten(data.get("grid", {})).items()]
        for group in data.get("zip", []):
            axes.append(Axis({k: _values(k, v) for k, v in _flatten(group).items()}))
        models = []
        for m in data.get("models", []):
            if not isinstance(m, dict) or "name" not in m:
                raise InputError("sweep spec: every [[models]] table needs a name")
            models.append(ModelSpec(str(m["name"]), {k: v for k, v in m.items() if k != "name"}))
        return cls(scene, tuple(axes), tuple(models), tuple(overrides),
                   str(data.get("name", default_name)), str(data.get("on_invalid", "error")))


def _is_preset(name: str) -> bool:
    from scenes import preset_names

    return name in preset_names()


def _flatten(table: dict, prefix: str = "") -> dict:
    """Nested TOML tables to dotted keys; range tables are leaves."""
    if not isinstance(table, dict):
        raise InputError(f"sweep spec: [grid] and [[zip]] must be tables, got {table!r}")
    out = {}
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and not (set(v) <= _RANGE_KEYS and "num" in v):
            out.update(_flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _describe(point: dict) -> str:
    return " ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                    for k, v in point.items()) or "base scene"


# --- cost --------------------------------------------------------------------------------
def _pillars_touching(scene: Scene) -> float:
    """Rough count of pillars in contact: Phi times the area 1.5 pi R zeta over a pillar top
    (1.5 R zeta lies between the rigid overlap R zeta and the elastic 2 R zeta)."""
    if scene.pillars is None:
        return 0.0
    r_top = scene.pillars.diameter_m / 2.0
    area = 1.5 * scene.lens.radius_m * scene.indentation_m
    return max(1.0, scene.pillars.surface_fraction * area / r_top**2)


def estimate_seconds(case: Case) -> float:
    """A rough single-core wall time (s) of a case, from a few solves measured on this
    2-core machine; a stand-in until the planner's measured cost models exist."""
    scene, o = case.scene, case.options
    touching = max(1.0, _pillars_touching(scene))
    if case.model == "bem":
        p = o.get("elements_per_diameter", 11)
        elements = 1.07 * touching * math.pi / 4 * p * p
        return 0.01 + 2e-5 * elements + 5e-9 * elements**2
    if case.model == "bem-fft":
        n = o.get("cells_per_diameter", 32)
        return 0.01 + 3.5e-5 * 1.5 * touching * math.pi / 4 * n * n
    if case.model == "fem-axisym":
        return 1.1 * float(o.get("mesh_size", 1.0)) ** -2.5
    return 1.0


def estimate_cost(cases: list[SweepCase], folder: Path | None, workers: int) -> dict:
    """Case count, how many are cached already, and the estimated time of the rest."""
    store = CaseStore(folder) if folder is not None else None
    per_model: dict[str, dict] = {}
    for c in cases:
        m = per_model.setdefault(c.case.model, {"cases": 0, "cached": 0, "seconds": 0.0})
        m["cases"] += 1
        if store is not None and store.load(c.case)[0] is not None:
            m["cached"] += 1
        else:
            m["seconds"] += estimate_seconds(c.case) * c.case.repeats
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
                **mat("substrate", scene.substrate),
                "load.indentation_um": scene.indentation_m * 1e6})
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


def run_sweep(sweep: Sweep, out: Path, *, engine: Engine | None = None) -> list[dict]:
    """Run (or resume, from ``out/cases``) every case; returns the table's rows."""
    cases, skipped = sweep.cases()
    own = engine is None
    engine = engine or Engine("serial")
    try:
        outcomes = engine.run([c.case for c in cases], Path(out) / "cases", label="sweep")
    finally:
        if own:
            engine.close()
    option_names = sorted({k for c in cases for k in c.case.options})
    rows = []
    for c, o in zip(cases, outcomes):
        cols = scene_columns(c.scene)
        cols.update(_file_units(sweep, c.point))
        row = {k: c.point[k] for k in sweep.keys}
        row.update({k: v for k, v in cols.items() if k not in row})
        row["model"] = c.case.model
        row.update({f"option.{k}": c.case.options.get(k) for k in option_names})
        if o.ok:
            r = o.result
            row.update({"total_force_N": r.total_force_N,
                        "centre_pressure_Pa": r.centre_pressure_Pa,
                        "contact_radius_m": r.contact_radius_m,
                        "real_contact_area_m2": r.real_contact_area_m2,
                        "pillars_in_contact": r.pillars_in_contact, "iterations": r.iterations,
                        "converged": bool(r.converged),
                        "wall_time_s": o.timing["wall_time_s"],
                        "peak_memory_MB": o.timing["peak_memory_MB"], "status": "ok"})
        else:
            row.update(dict.fromkeys(RESULT_COLUMNS))
            row["status"] = f"failed: {o.error}"
        row["case_key"] = c.case.key
        rows.append(row)
    return rows


def table_columns(rows: list[dict]) -> list[str]:
    return list(rows[0]) if rows else [*SCENE_COLUMNS, "model", *RESULT_COLUMNS]


def write_table(rows: list[dict], out: Path, name: str) -> list[Path]:
    """``<name>.csv`` and ``<name>.parquet`` in ``out`` (atomically); returns their paths."""
    from scenes import atomic_path

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
