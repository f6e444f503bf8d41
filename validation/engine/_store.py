"""The case folder: one JSON record per finished case, its companion files, per-case locks and
a journal.

Layout of a folder::

    <stem>.json            the record: key, code version, case, result, timing, files
    <stem>.fields.vtu      companion files a case asked for (a model's VTU and its sidecar)
    .locks/<key>.lock      held (fcntl.flock) while a process computes the case
    journal.jsonl          one line per start, finish or failure: who computed what

A record is trusted only if it passes :meth:`CaseStore.load`'s checks: the SHA-256 of its
own content, then the cached operators its result was computed with (an elastic pillar's
compliance: their content hashes, in the result's ``diagnostics["operators"]``, must be the
ones the caches hold now, so a case computed with an operator that was since replaced or
repaired is not reused); anything else is recomputed.  Records and companions are written
atomically (companions first, the record last, naming their sizes and SHA-256), so the
presence of a valid record means the whole case is on disk.  Locks are advisory ``flock``
locks, which the kernel releases when their holder dies, even by ``kill -9``: no stale lock
survives a crash.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from pathlib import Path

from pillar_xval.outcome import ContactResult, FileLock, write_atomic
from pillar_xval.scenes import ToolError

from ._case import Case, accepts_vtu, code_version

# 2: the record carries the SHA-256 of its own content (``digest``).
RECORD_FORMAT = 2
# Pillar forces are sums over the same cells as the total force: they agree to round-off
# (measured <= 1e-15 relative on the dense BEM); a doubled or lost force is O(1).  A
# converged force-controlled result carries the given force within its solver's tolerance
# (1e-8 at most, the secants'; the others to round-off): the same bound holds it.
RTOL_FORCE_SUM = 1e-6


def _no_constants(name: str):
    raise ValueError(f"non-finite number {name}")


def _all_finite(obj, path: str = "record") -> str:
    """'' when every float in ``obj`` is finite, else where the first one is not."""
    if isinstance(obj, float):
        return "" if math.isfinite(obj) else path
    if isinstance(obj, dict):
        for k, v in obj.items():
            bad = _all_finite(v, f"{path}.{k}")
            if bad:
                return bad
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            bad = _all_finite(v, f"{path}[{i}]")
            if bad:
                return bad
    return ""


def _digest(record: dict) -> str:
    """SHA-256 of the record's canonical JSON without its ``digest``: any edit of a value
    (a pressure scaled by 1.1, a radius by 3) changes it."""
    body = {k: v for k, v in record.items() if k != "digest"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _operator_changed(record: dict) -> str:
    """'' while the caches still hold every operator the case was computed with (the content
    hashes its result names in ``diagnostics["operators"]``), else which one they do not."""
    from ..registry import stored_operator

    for used in record["result"].get("diagnostics", {}).get("operators", []):
        now = stored_operator(used.get("store"), used.get("key"))
        if now != used.get("sha256"):
            held = "no valid one" if now is None else f"content {now[:12]}"
            return (f"computed with the {used.get('store')} operator {used.get('key')} of "
                    f"content {str(used.get('sha256'))[:12]}, the cache now holds {held}")
    return ""


class CaseStore:
    """The cases of one study folder (see the module docstring)."""

    def __init__(self, folder: str | os.PathLike):
        self.folder = Path(folder)

    # --- paths ---
    def record_path(self, case: Case) -> Path:
        return self.folder / f"{case.stem}.json"

    def companion_path(self, case: Case, name: str) -> Path:
        """``fields.vtu`` -> ``<stem>.fields.vtu``."""
        return self.folder / f"{case.stem}.{name}"

    def _lock_path(self, case: Case) -> Path:
        return self.folder / ".locks" / f"{case.key}.lock"

    # --- reading ---
    def load(self, case: Case) -> tuple[dict | None, str]:
        """(record, '') for a valid record of ``case``; (None, reason) otherwise (reason ''
        when there is no record at all)."""
        path = self.record_path(case)
        if not path.exists():
            return None, ""
        try:
            record = json.loads(path.read_text(), parse_constant=_no_constants)
        # RecursionError: arrays nested thousands deep (an edited or damaged file).
        except (OSError, ValueError, UnicodeDecodeError, RecursionError) as exc:
            return None, f"unreadable ({str(exc)[:200]})"
        try:
            reason = self._check(case, record)
        except (AttributeError, KeyError, TypeError, ValueError) as exc:
            reason = f"malformed record ({type(exc).__name__}: {exc})"
        return (None, reason) if reason else (record, "")

    def _check(self, case: Case, record) -> str:
        if not isinstance(record, dict) or record.get("format") != RECORD_FORMAT:
            return "not a case record of this format"
        if record.get("key") != case.key:
            return f"key {record.get('key')!r} is not the case's {case.key}"
        if record.get("code_version") != code_version():
            return f"code version {record.get('code_version')!r} is not {code_version()}"
        if record.get("case", {}).get("model") != case.model:
            return "model differs from the case's"
        bad = _all_finite(record)
        if bad:
            return f"non-finite number at {bad}"
        try:
            result = ContactResult.from_dict(record["result"])
        except (KeyError, TypeError, ValueError) as exc:
            return f"result does not parse ({type(exc).__name__}: {exc})"
        force = case.scene.force_N
        if force is not None and result.converged and \
                abs(result.total_force_N - force) > RTOL_FORCE_SUM * force:
            return (f"carries {result.total_force_N:.9g} N, the case's force is "
                    f"{force:.9g} N")
        if result.pillar_forces:
            # The floor between the pillars carries the rest of a mixed contact's load.
            total = sum(p.force_N for p in result.pillar_forces) + result.floor_force_N
            if abs(total - result.total_force_N) > RTOL_FORCE_SUM * abs(result.total_force_N):
                return (f"pillar and floor forces sum to {total:.9g} N, total force is "
                        f"{result.total_force_N:.9g} N")
        timing = record.get("timing")
        if not isinstance(timing, dict) or not isinstance(timing.get("wall_time_s"), float):
            return "timing missing"
        if timing.get("repeats_requested", 1) < case.repeats:
            return f"timed {timing.get('repeats_requested', 1)} time(s), {case.repeats} asked"
        if case.vtu and accepts_vtu(case.model) and "fields.vtu" not in record.get("files", {}):
            return "the case asks for the VTU, the record has none"
        if case.fields and "fields.npz" not in record.get("files", {}):
            return "the case asks for the result's arrays, the record has none"
        for name, meta in record.get("files", {}).items():
            reason = self._check_companion(case, name, meta)
            if reason:
                return reason
        if record.get("digest") != _digest(record):
            return "content changed after it was written (its digest does not match)"
        return _operator_changed(record)

    def _check_companion(self, case: Case, name: str, meta: dict) -> str:
        path = self.companion_path(case, name)
        try:
            size = path.stat().st_size
        except OSError:
            return f"companion {path.name} missing"
        if size != meta.get("bytes") or _sha256(path) != meta.get("sha256"):
            return f"companion {path.name} truncated or changed ({size} bytes, " \
                   f"{meta.get('bytes')} recorded)"
        try:
            if name.endswith(".vtu"):
                import meshio

                meshio.read(path)
            elif name.endswith(".npz"):
                import numpy as np

                with np.load(path) as data:
                    data.files  # noqa: B018  (reads the archive's directory)
        except Exception as exc:  # any parser failure means an unusable file
            return f"companion {path.name} does not parse ({type(exc).__name__})"
        return ""

    def result_of(self, record: dict) -> ContactResult:
        return ContactResult.from_dict(record["result"])

    def companions(self, case: Case, record: dict) -> dict[str, Path]:
        return {name: self.companion_path(case, name) for name in record.get("files", {})}

    # --- writing ---
    def save(self, case: Case, payload: dict) -> dict:
        """Write the companions, then the record (each atomically); returns the record."""
        files = {}
        for name, data in sorted(payload.get("files", {}).items()):
            write_atomic(self.companion_path(case, name), data)
            files[name] = {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
        record = {"format": RECORD_FORMAT, "key": case.key, "code_version": code_version(),
                  "case": {"model": case.model, "scene": case.scene.to_dict(),
                           "options": dict(case.options), "repeats": case.repeats,
                           "vtu": case.vtu, "fields": case.fields},
                  "result": payload["result"], "timing": payload["timing"], "files": files,
                  "worker": payload.get("worker", {}), "finished": time.time()}
        try:
            record["digest"] = _digest(record)
            text = json.dumps(record, indent=1, allow_nan=False)
        except ValueError as exc:
            raise ToolError(f"case {case.key}: result holds a non-finite number ({exc})") from None
        write_atomic(self.record_path(case), text)
        return record

    # --- locks and journal ---
    def try_lock(self, case: Case) -> FileLock | None:
        """The case's lock, or None while another process holds it."""
        path = self._lock_path(case)
        try:
            return FileLock.acquire(path, wait=False)
        except (OSError, ValueError) as exc:
            raise ToolError(f"cannot lock {path}: {exc}") from None

    def journal(self, event: str, case: Case, **extra) -> None:
        """Append one line (a single small O_APPEND write: lines of concurrent processes never
        interleave)."""
        line = json.dumps({"event": event, "key": case.key, "model": case.model,
                           "options": case.options, "pid": os.getpid(), "time": time.time(),
                           **extra}, default=str) + "\n"
        self.folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.folder / "journal.jsonl", os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line.encode())
        finally:
            os.close(fd)


def read_journal(folder: str | os.PathLike) -> list[dict]:
    """The journal's events, oldest first (a torn last line, from a killed writer, is
    skipped)."""
    path = Path(folder) / "journal.jsonl"
    if not path.exists():
        return []
    events = []
    for line in path.read_text().splitlines():
        try:
            events.append(json.loads(line))
        except (ValueError, RecursionError):  # a damaged line
            continue
    return events
