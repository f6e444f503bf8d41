"""The grid of a sweep: values (lists, linear and log ranges), axes (crossed, or zipped keys
that vary together), models with option grids, and the spec file that declares them.  The
format is documented in :mod:`validation.studies.sweep`."""

from __future__ import annotations

import itertools
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from pillar_xval.scenes import InputError, Scene, SceneError, ScopeError, scene_loader

from ...engine import Case

_RANGE_KEYS = {"linear", "log", "num"}
# What a grid holds in memory, measured by `python -m validation.bench.sweep` (make
# bench-sweep): each value of an axis (its float, and its text while repeated values are
# looked for) 144 bytes; each case of a run (its scene, the engine's case, its outcome, its
# table row and the written table) 39.8 kB with the densest paper scene's result (151 pillar
# forces; 11 kB with the sparse scene's).  A grid is sized from its spec before any of it is
# built, and refused when that cannot fit in the memory a process may take
# (pillar_xval.outcome.memory).
BYTES_PER_AXIS_VALUE = 150
BYTES_PER_CASE = 40_000


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


def _length(key: str, spec) -> int:
    """How many values ``spec`` (as :func:`_values` reads it) stands for, without them."""
    if isinstance(spec, list):
        return len(spec)
    if isinstance(spec, dict) and set(spec) <= _RANGE_KEYS and "num" in spec:
        num = spec["num"]
        # An invalid num is refused by _values, which reads it next.
        return num if isinstance(num, int) and not isinstance(num, bool) and num > 0 else 1
    return 1


def check_size(points: int, values: int, cases: int | None = None) -> None:
    """Refuse a grid that cannot fit: its axes' ``values`` (always built), and with
    ``cases`` the cases of a whole run (a dry run samples a few)."""
    from pillar_xval.outcome.memory import memory_short

    short = memory_short(values * BYTES_PER_AXIS_VALUE)
    if short is not None:
        raise InputError(f"sweep grid: its axes hold {values:,} values (about "
                         f"{values * BYTES_PER_AXIS_VALUE / 2**30:.3g} GiB), {short}; "
                         "use fewer values")
    if cases is None:
        return
    short = memory_short(cases * BYTES_PER_CASE)
    if short is not None:
        raise InputError(f"sweep grid: {points:,} points give {cases:,} cases; a run holds "
                         f"each in memory (about {BYTES_PER_CASE / 1e3:.0f} kB): "
                         f"{cases * BYTES_PER_CASE / 2**30:.3g} GiB, {short}; split it into "
                         "smaller sweeps")


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
        seen, repeated = set(), set()
        for p in zip(*self.values.values()):
            text = repr(p)
            (repeated if text in seen else seen).add(text)
        repeated = sorted(repeated)
        if repeated:
            raise InputError(f"{', '.join(self.values)}: value(s) given more than once "
                             f"({', '.join(repeated)}); each point of the grid is one case")

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

    def point_count(self) -> int:
        """How many grid points (the product of the axes' lengths), without listing them."""
        return math.prod(len(a) for a in self.axes)

    def case_count(self) -> int:
        """How many cases a run holds: the points times every model's option sets."""
        return self.point_count() * sum(
            math.prod(len(v) if isinstance(v, list) else 1 for v in m.options.values())
            for m in self.models)

    def point(self, index: int) -> dict:
        """Grid point ``index`` in :meth:`points` order (mixed radix, the last axis fastest)."""
        point = {}
        for a in reversed(self.axes):
            index, i = divmod(index, len(a))
            point = {**a.point(i), **point}
        return point

    def points(self) -> list[dict]:
        """Every grid point, the first axis varying slowest."""
        out = []
        for idx in itertools.product(*(range(len(a)) for a in self.axes)):
            point = {}
            for a, i in zip(self.axes, idx):
                point.update(a.point(i))
            out.append(point)
        return out

    def cases(self, indices=None) -> tuple[list[SweepCase], list[tuple[dict, str]]]:
        """(cases, skipped points with the reason), of every point or of the points
        ``indices``.  A point the scene refuses raises an InputError naming the point, unless
        ``on_invalid = "skip"``."""
        from ...planner.features import scope_refusal
        from ...registry import check_options, scene_defaults

        if indices is None:  # sized before anything is built, the models' option sets too
            check_size(self.point_count(), sum(len(a) for a in self.axes), self.case_count())
        for m in self.models:  # values a model would refuse, before any solve
            for opts in m.option_sets():
                check_options(m.name, opts, "[[models]]")
        out, skipped = [], []
        load = scene_loader(self.scene)  # the scene file is read once, not once per point
        points = self.points() if indices is None else [self.point(i) for i in indices]
        for point in points:
            sets = [*self.overrides, *(_override(k, v) for k, v in point.items())]
            try:
                scene = load(sets)
            except SceneError as exc:
                if self.on_invalid == "skip":
                    skipped.append((point, str(exc)))
                    continue
                raise SceneError(f"sweep point {_describe(point)}: {exc}") from None
            refused = _refused(self.models, scene, scope_refusal)
            if refused is not None:
                if self.on_invalid == "skip":
                    skipped.append((point, refused))
                    continue
                raise ScopeError(f"sweep point {_describe(point)}: {refused} (on_invalid = "
                                 "\"skip\" leaves such points out)")
            for m in self.models:
                for opts in m.option_sets():
                    out.append(SweepCase(point, scene, Case(
                        m.name, scene, scene_defaults(m.name, scene, opts),
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
        except OSError as exc:
            raise InputError(f"sweep spec {str(path)!r}: cannot read it "
                             f"({exc.strerror or exc})") from None
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
        grid = _flatten(data.get("grid", {}))
        groups = [_flatten(group) for group in data.get("zip", [])]
        # The grid's size from the spec alone, before a value is built (a zipped group's
        # keys have equal lengths, or Axis refuses them).
        spec_axes = [{k: v} for k, v in grid.items()] + groups
        lengths = [{k: _length(k, v) for k, v in axis.items()} for axis in spec_axes]
        check_size(math.prod(max(n.values(), default=1) for n in lengths),
                   sum(sum(n.values()) for n in lengths))
        axes = [Axis({k: _values(k, v) for k, v in axis.items()}) for axis in spec_axes]
        models = []
        for m in data.get("models", []):
            if not isinstance(m, dict) or "name" not in m:
                raise InputError("sweep spec: every [[models]] table needs a name")
            models.append(ModelSpec(str(m["name"]), {k: v for k, v in m.items() if k != "name"}))
        name = str(data.get("name", default_name))
        if name in ("", ".", "..") or Path(name).name != name or "\\" in name or "\0" in name:
            raise InputError(f"sweep spec: name = {name!r}: the table files' stem must be a plain "
                             "file name (no folder, not '..'), so the table stays inside --out")
        return cls(scene, tuple(axes), tuple(models), tuple(overrides),
                   name, str(data.get("on_invalid", "error")))


def _refused(models, scene: Scene, scope_refusal) -> str | None:
    """Why a model of the sweep cannot run ``scene`` (its declared scope, or an elastic
    pillar on a flat scene), or None."""
    from ...registry import check_options

    for m in models:
        why = scope_refusal(m.name, scene)
        if why is not None:
            return why
        for opts in m.option_sets():
            try:
                check_options(m.name, opts, "[[models]]", scene)
            except InputError as exc:
                return str(exc)
    return None


def _is_preset(name: str) -> bool:
    from pillar_xval.scenes import preset_names

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
