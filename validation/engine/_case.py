"""A case: one model on one scene with its options; its key; and its computation.

How the code enters the key
---------------------------
:func:`case_key` hashes, as canonical JSON (sorted keys, no whitespace), the scene's physics
(every SI field of ``Scene.to_dict`` except its name), the model's name, its options,
:func:`code_version` and the model's own code (:func:`model_code`).  The code version is the
package version followed by the first 12 hex digits of a SHA-256 over the source and data
files (``*.py``, ``*.toml``, ``*.json``, with their relative paths) of
:data:`COMPUTING_PACKAGES`, what decides every result: the physics (``pillar_xval``:
the result schema, scenes, contact and closed forms; ``bem_solver``, ``meshes``,
``fem_reference``), the model
registry (``validation.registry``: which options reach a solver) and this module (how a case
runs).  A model that computes with
more (``auto``: the planner, ``validation.planner``, and its data) declares it in its
``code`` (:class:`validation.registry.Model`), and its keys hash that too, so a recalibration
gives ``auto`` new keys and leaves every other model's cache alone.  Digests are computed once
per process.  Any edit to those files gives the cases it can change a new key, so a cached
result of older code is never reused; the old files stay on disk, unused.  Edits elsewhere in
``validation/`` (studies, analysis, output, the CLI) do not change results and do not change
the key.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import importlib.util
import json
import os
import socket
import statistics
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from pillar_xval.outcome import ContactResult, package_version
from pillar_xval.scenes import Scene, ToolError

from ._progress import SolveProgress

# The packages and modules whose source decides every result (module docstring).
COMPUTING_PACKAGES = ("pillar_xval", "bem_solver", "meshes", "fem_reference",
                      "validation.registry", "validation.engine._case")
# The files of a package that enter its digest: source, and the data it reads.
SOURCE_SUFFIXES = (".py", ".toml", ".json")


def source_digest(roots: dict[str, Path | None]) -> str:
    """12 hex digits of SHA-256 over the :data:`SOURCE_SUFFIXES` files under each root (name
    -> folder, or one module's file; None for an absent package), with their relative paths,
    in sorted order."""
    digest = hashlib.sha256()
    for name in sorted(roots):
        root = roots[name]
        if root is None:
            digest.update(f"{name}:absent".encode())
            continue
        root = Path(root)
        files = [root] if root.is_file() else sorted(
            p for p in root.rglob("*")
            if p.suffix in SOURCE_SUFFIXES and "__pycache__" not in p.parts)
        for path in files:
            relative = path.name if path == root else path.relative_to(root).as_posix()
            digest.update(f"{name}/{relative}\0".encode())
            digest.update(path.read_bytes())
            digest.update(b"\0")
    return digest.hexdigest()[:12]


def package_root(name: str) -> Path | None:
    """The folder of package ``name``, the file of module ``name``, or None when absent."""
    spec = importlib.util.find_spec(name)
    if spec is None:
        return None
    locations = list(spec.submodule_search_locations or [])
    if locations:
        return Path(locations[0])
    return Path(spec.origin) if spec.origin else None


@functools.cache
def code_digest(names: tuple[str, ...]) -> str:
    """:func:`source_digest` of the packages or modules ``names``."""
    return source_digest({name: package_root(name) for name in names})


@functools.lru_cache(maxsize=1)
def code_version() -> str:
    """``<package version>+src.<12 hex digits>``: see the module docstring."""
    return f"{package_version()}+src.{code_digest(COMPUTING_PACKAGES)}"


def model_code(model: str) -> str | None:
    """The digest of what ``model`` computes with beyond :data:`COMPUTING_PACKAGES` (its
    declaration's ``code``), None for a model that declares nothing more."""
    from ..registry import MODELS

    declared = MODELS[model].code if model in MODELS else ()
    return code_digest(tuple(declared)) if declared else None


def canonical_json(obj) -> str:
    """Sorted keys, no whitespace, no NaN: equal objects give equal text."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def scene_physics(scene: Scene) -> dict:
    """The scene's SI description without its name."""
    return {k: v for k, v in scene.to_dict().items() if k != "name"}


def case_key(model: str, scene: Scene, options: dict, version: str | None = None) -> str:
    """16 hex digits of SHA-256 over the scene's physics, the model, its options and the code
    version (default :func:`code_version`): equal keys mean equal computations."""
    payload = {"scene": scene_physics(scene), "model": model, "options": dict(options),
               "code": code_version() if version is None else version}
    own = model_code(model)
    if own is not None:
        payload["model_code"] = own
    text = canonical_json(payload)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class Case:
    """One computation: ``model`` on ``scene`` with ``options``.

    ``repeats`` timed runs (the median is kept; a first run slower than ``single_above``
    seconds is not repeated), ``vtu`` (ask a model that can write one for its VTU fields) and
    ``fields`` (keep the result's numeric arrays, e.g. a pressure map, as ``fields.npz``) say
    how to run it; they are not part of the key, since they do not change the result: a
    cached case with fewer repeats, or without a file the case asks for, is recomputed.
    ``tag`` labels the case in progress lines.
    """

    model: str
    scene: Scene
    options: dict = field(default_factory=dict)
    repeats: int = 1
    single_above: float = float("inf")
    vtu: bool = False
    fields: bool = False
    tag: str = ""

    @functools.cached_property
    def key(self) -> str:
        return case_key(self.model, self.scene, self.options)

    @property
    def stem(self) -> str:
        """Readable, unique file stem: model, options, then the key."""
        opts = "-".join(f"{k}={v}" for k, v in sorted(self.options.items()))
        return f"{self.model}-{opts}-{self.key}".replace("/", "_").replace(" ", "")

    def describe(self) -> str:
        opts = " ".join(f"{k}={v}" for k, v in sorted(self.options.items()))
        return f"{self.tag + ': ' if self.tag else ''}{self.model} {opts}".strip()

    def spec(self) -> dict:
        """What a worker needs (plain data: crosses process and machine boundaries)."""
        return {"model": self.model, "scene": self.scene.to_dict(), "options": dict(self.options),
                "key": self.key, "code_version": code_version(),
                "model_code": model_code(self.model), "repeats": self.repeats,
                "tag": self.describe(),
                "single_above": self.single_above, "vtu": self.vtu, "fields": self.fields}


def accepts_vtu(model: str) -> bool:
    """Whether the model's function takes ``vtu_path`` (it writes its fields as VTU)."""
    from ..registry import get_model

    return get_model(model).takes("vtu_path")


# --- memory ------------------------------------------------------------------------------
def _status_kib(field_name: str) -> int | None:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(field_name + ":"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def _reset_peak() -> bool:
    """Reset the process's peak resident set (Linux >= 4.0: writing 5 to clear_refs)."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def _release_free_memory() -> None:
    """Hand memory freed by earlier cases back to the system (glibc ``malloc_trim``), so that
    the next case's allocations show in the resident set instead of reusing free heap."""
    import gc

    gc.collect()
    # What survives a full collection is long-lived (modules, caches): freezing it keeps the
    # next case's collection to that case's own objects (a full pass over a worker's heap
    # took 25-57 ms, more than many solves).
    gc.freeze()
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _measured_run(run) -> tuple[ContactResult, float, dict]:
    """One run: (result, wall time s, memory dict).  Peak memory is the resident set's high
    water mark (VmHWM) after resetting it, so C buffers count and nothing slows the run;
    ``peak_memory_MB`` is what the run added to the resident set it started from (freed
    memory of earlier cases is first handed back to the system)."""
    _release_free_memory()
    reset = _reset_peak()
    rss0 = _status_kib("VmRSS")
    start = time.perf_counter()
    result = run()
    wall = time.perf_counter() - start
    hwm = _status_kib("VmHWM")
    if reset and hwm is not None and rss0 is not None:
        memory = {"peak_memory_MB": max(hwm - rss0, 0) / 1024.0, "peak_rss_MB": hwm / 1024.0,
                  "memory_method": "VmHWM reset by /proc/self/clear_refs, minus VmRSS at start"}
    else:
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        memory = {"peak_memory_MB": peak, "peak_rss_MB": peak,
                  "memory_method": "ru_maxrss of the worker process (an upper bound)"}
    return result, wall, memory


def _npz_bytes(fields: dict) -> bytes:
    """The numeric arrays and numbers of ``fields`` as a compressed ``.npz`` (objects such
    as a discretisation are left out: they need pickling to be read back)."""
    import io

    import numpy as np

    arrays = {}
    for name, value in fields.items():
        array = np.asarray(value) if isinstance(value, (list, tuple, float, int, np.ndarray)) \
            else None
        if array is not None and array.dtype.kind in "biuf":
            arrays[name] = array
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def compute_case(spec: dict) -> dict:
    """Run one case (in a worker: a pool process, a Dask worker or the parent).

    Returns plain data: the result (JSON-ready dict), the timing (median wall time over the
    repeats, every run's time, peak memory), the companion files as bytes (the parent writes
    them, so a Dask worker needs no shared file system), and where it ran.  Exceptions of the
    model propagate unchanged.
    """
    mine = code_version()
    if mine != spec["code_version"] or model_code(spec["model"]) != spec.get("model_code"):
        raise ToolError(f"worker {socket.gethostname()} runs code {mine} "
                        f"({spec['model']}: {model_code(spec['model'])}), the study expects "
                        f"{spec['code_version']} ({spec.get('model_code')}): install the same "
                        "toolkit on every worker")
    from ..registry import run_model

    scene = Scene.from_dict(spec["scene"])
    model, options = spec["model"], spec["options"]
    files: dict[str, bytes] = {}
    with tempfile.TemporaryDirectory(prefix="pillar-xval-case-") as tmp:
        vtu_path = Path(tmp) / "fields.vtu" if spec.get("vtu") else None
        # Lines inside a long first run (on the worker's stderr); the timing repeats are quiet.
        with SolveProgress(spec.get("tag") or model, every_s=10.0) as progress:
            result, wall, memory = _measured_run(lambda: run_model(
                model, scene, vtu_path=vtu_path, progress=progress, **options))
        for path in sorted(Path(tmp).iterdir()):
            files[path.name] = path.read_bytes()
    if spec.get("fields"):
        files["fields.npz"] = _npz_bytes(result.fields)
    times = [wall]
    if wall <= spec.get("single_above", float("inf")):
        for _ in range(max(1, int(spec.get("repeats", 1))) - 1):
            start = time.perf_counter()
            run_model(model, scene, **options)
            times.append(time.perf_counter() - start)
    timing = {"wall_time_s": statistics.median(times), "wall_times_s": times,
              "repeats": len(times), "repeats_requested": int(spec.get("repeats", 1)),
              **memory}
    return {"result": result.to_dict(), "timing": timing, "files": files,
            "worker": {"host": socket.gethostname(), "pid": os.getpid()}, "code_version": mine}
