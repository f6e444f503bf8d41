"""Ctrl-C and SIGTERM during every tool end the command at once with 130 or 143 and one line:
gmsh meshing in each of the three mesh builders (whose Python size callback once
swallowed the signal: exit 3, or a sweep that ran on with a different mesh and cached it),
a long library call (a PARDISO factorisation), a serial sweep and a pool.

Each run is a real CLI process.  The signal is sent by a thread of that process 10 ms after
the size rule's 300th call (so it arrives while gmsh meshes, every time, and Python takes it
as a later call enters gmsh's own wrapper of the rule, where no ``try`` of ours can catch
it), or from the test once a stand-in for a factorisation has started.  Each test takes a
few seconds.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

# Seconds from the signal to the end of the process: the watchdog's grace
# (validation.cli._signals.GRACE_S, 1 s) and the interpreter's exit, with room for a loaded
# machine.  The stand-in factorisation below runs for minutes.
PROMPT_S = 8.0
RUN = """
import hashlib, os, signal, sys, time

def mark():
    with open(os.environ["MARK"], "w") as fh:
        fh.write(repr(time.time()))

def counting(fn, at, signum):
    # The signal comes from another thread 10 ms later, as from outside while gmsh runs:
    # Python runs its handler at the main thread's next chance, as a later size call enters
    # gmsh's own wrapper of the rule.
    import threading
    calls = [0]
    def size(*args):
        calls[0] += 1
        if calls[0] == at:
            mark()
            def later():
                time.sleep(0.01)
                os.kill(os.getpid(), signum)
            threading.Thread(target=later).start()
        return fn(*args)
    return size

%s
from validation.cli import main
sys.exit(main(sys.argv[1:]))
"""
# The size rule of each builder, counted; the signal at its AT-th call.
BUILDERS = {
    "axisymmetric": (
        "import meshes.axisym.geometry as g\n"
        "g.AxisymmetricGeometry.size_at = counting(g.AxisymmetricGeometry.size_at, AT, SIG)",
        ["solve", "--model", "fem-axisym", "--scene", "single-pillar", "--json"]),
    "sector (fem-3d)": (
        "import meshes.wedge.geometry as g\n"
        "rule = g.WedgeGeometry.size_callback\n"
        "g.WedgeGeometry.size_callback = lambda self: counting(rule(self), AT, SIG)",
        ["solve", "--model", "fem-3d", "--scene", "single-pillar", "--mesh-size", "4",
         "--json"]),
    "pillar compliance": (
        "import fem_reference._pillar_compliance as pc\n"
        "rule = pc._size_rule\n"
        "pc._size_rule = lambda *a: counting(rule(*a), AT, SIG)",
        ["solve", "--scene", "single-pillar", "--elements-per-diameter", "5", "--pillars",
         "elastic", "--json"]),
}
STATUS = {signal.SIGINT: (130, "interrupted"),
          signal.SIGTERM: (143, "terminated (SIGTERM); finished cases are kept")}


def _start(tmp_path, patch: str, argv, **kwargs):
    env = {**os.environ, "MARK": str(tmp_path / "mark"),
           "PILLAR_XVAL_CACHE": str(tmp_path / "cache")}
    return subprocess.Popen([sys.executable, "-c", RUN % patch, *map(str, argv)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=tmp_path, **kwargs)


def _ended(proc, tmp_path, signum, timeout=120) -> str:
    """Wait for the end; check the status, the one line and the time since the signal."""
    out, err = proc.communicate(timeout=timeout)
    took = time.time() - float((tmp_path / "mark").read_text())
    code, line = STATUS[signum]
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("[")]
    assert proc.returncode == code, err[-2000:]
    assert len(lines) == 1 and lines[0].endswith(line), err[-2000:]
    assert "Exception ignored" not in err and "Traceback" not in err
    assert took < PROMPT_S, f"{took:.1f} s from the signal to the end"
    return err


# Each builder once, both signals among them (the serial sweep below adds SIGTERM in the
# axisymmetric builder, the factorisation both signals in the compliance build).
@pytest.mark.parametrize("builder, signum", [
    ("axisymmetric", signal.SIGINT), ("sector (fem-3d)", signal.SIGTERM),
    ("pillar compliance", signal.SIGINT)], ids=["axisymmetric", "sector", "compliance"])
def test_a_signal_while_gmsh_meshes(tmp_path, builder, signum):
    patch, argv = BUILDERS[builder]
    proc = _start(tmp_path, patch.replace("AT", "300").replace("SIG", str(int(signum))),
                  argv)
    _ended(proc, tmp_path, signum)
    # Nothing half-made is cached: no compliance file, no temporary file.
    cache = tmp_path / "cache" / "pillar-compliance"
    left = [p.name for p in cache.iterdir() if p.name != ".locks"] if cache.is_dir() else []
    assert left == []


SWEEP = """scene = "single-pillar"
[grid]
"load.indentation_um" = [0.2, 0.3]
[[models]]
name = "fem-axisym"
mesh_size = 0.5
"""


def test_a_serial_sweep_stops_at_a_sigterm_while_gmsh_meshes(tmp_path):
    """A SIGTERM 0.8 s into meshing was once lost: the sweep ran on, exited 0 and cached a
    case meshed with 5500 instead of 5519 elements."""
    (tmp_path / "s.toml").write_text(SWEEP)
    patch = BUILDERS["axisymmetric"][0].replace("AT", "300").replace("SIG", "15")
    proc = _start(tmp_path, patch, ["sweep", "s.toml", "--out", "o", "--executor", "serial"])
    _ended(proc, tmp_path, signal.SIGTERM)
    cases = tmp_path / "o" / "cases"
    assert not list(cases.glob("*.json"))
    events = [json.loads(ln)["event"] for ln in (cases / "journal.jsonl").read_text().split("\n")
              if ln]
    assert events == ["start"]


# A stand-in for a long factorisation: PBKDF2 runs in C, holds no Python frame and releases
# the interpreter's lock, as MKL PARDISO does, for minutes; Python's handler would run only
# when it returns.
STAND_IN = """
import fem_reference._pillar_compliance as pc
build = pc.compute_modal_compliance  # coarse, to reach the first factorisation in a second
pc.compute_modal_compliance = lambda kind, modes, mesh, progress=None: build(kind, 1, 4.0,
                                                                             progress)
import fem_reference._pardiso as target
real = target.Pardiso._call
def slow(self, phase, b):
    if phase == 12:
        mark()
        hashlib.pbkdf2_hmac("sha256", b"pillar", b"xval", 10**9)
    return real(self, phase, b)
target.Pardiso._call = slow
"""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_during_a_long_factorisation(tmp_path, signum):
    """The compliance build's first PARDISO factorisation (a stand-in of minutes)."""
    proc = _start(tmp_path, STAND_IN, BUILDERS["pillar compliance"][1])
    deadline = time.time() + 120
    while not (tmp_path / "mark").exists() and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(0.2)
    (tmp_path / "mark").write_text(repr(time.time()))
    proc.send_signal(signum)
    try:
        _ended(proc, tmp_path, signum, timeout=PROMPT_S + 5)
    finally:
        proc.kill()


def _children(pid: int) -> list[int]:
    found = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            found += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return found


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs /proc")
def test_a_sigterm_ends_a_pool_and_its_workers(tmp_path):
    (tmp_path / "s.toml").write_text(SWEEP)
    proc = _start(tmp_path, "", ["sweep", "s.toml", "--out", "o", "--executor", "pool",
                                 "--workers", "2"])
    journal = tmp_path / "o" / "cases" / "journal.jsonl"
    deadline = time.time() + 120
    while time.time() < deadline and (not journal.exists()
                                      or journal.read_text().count('"start"') < 2):
        time.sleep(0.05)
    time.sleep(0.5)
    workers = _children(proc.pid)
    assert len(workers) >= 2
    (tmp_path / "mark").write_text(repr(time.time()))
    proc.send_signal(signal.SIGTERM)
    try:
        _ended(proc, tmp_path, signal.SIGTERM, timeout=PROMPT_S + 5)
    finally:
        proc.kill()
    time.sleep(0.5)
    assert not [w for w in workers if Path(f"/proc/{w}").exists()
                and "zombie" not in Path(f"/proc/{w}/status").read_text()]


# A signal whose handler runs in a __del__ (here: the object that sends it), where Python
# reports the exception as "ignored" and drops it.
IN_A_DESTRUCTOR = """
import pillar_xval.contact as contact
real = contact.solve_active_set
class Drop:
    def __del__(self):
        mark()
        os.kill(os.getpid(), SIG)
        sum(range(10))   # bytecode: the handler runs here, inside __del__
def solve(*args, **kwargs):
    Drop()
    return real(*args, **kwargs)
contact.solve_active_set = solve
import bem_solver._dense as dense
dense.solve_contact = solve
"""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_taken_where_python_cannot_raise_is_not_lost(tmp_path, signum):
    """Once dropped with "Exception ignored" (a __del__, a ctypes callback): the command ran
    on and exited 0."""
    proc = _start(tmp_path, IN_A_DESTRUCTOR.replace("SIG", str(int(signum))),
                  ["solve", "--scene", "hertz", "--elements-per-diameter", "5"])
    _ended(proc, tmp_path, signum)
