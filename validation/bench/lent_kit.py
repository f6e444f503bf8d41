"""The kit that lets a lent machine without gmsh, scikit-fem or MKL run fem-3d
(``python -m validation.bench.lent_kit build|unpack|check``).

A lent GPU machine has Python with numpy, scipy, threadpoolctl and the like, but not the
fem-3d path's packages, and it cannot fetch them; each call carries at most 64 MiB (the
tree included).  ``build`` (here) packs what it lacks from this checkout's environment into
two xz archives under ``.lent/`` (ignored by git), each small enough for one call:

- ``kit-mkl.tar.xz``: MKL's runtime for PARDISO: ``libmkl_rt``, ``libmkl_core``, the LP64
  interface, the GNU OpenMP threading layer (gmsh has loaded ``libgomp`` by the time MKL
  loads, and ``libmkl_rt`` then picks that layer; ``MKL_THREADING_LAYER=GNU`` makes it
  explicit) and the AVX-512 kernel with its vector-math library;
- ``kit-gmsh.tar.xz``: the pure-Python packages (scikit-fem, meshio and its ``rich``,
  pypardiso), gmsh's module and shared library, the system libraries ``libgmsh`` needs
  beyond glibc (X11, GL, fontconfig, ``libgomp``: a compute node may lack them; ``unpack``
  keeps only those the machine cannot load itself), and MKL's AVX2 kernel and its generic
  one ``libmkl_def`` (the one MKL picks on this AMD EPYC, for all its AVX-512), each with
  its vector-math library.  pymetis, compiled for this Python, is not carried: there fem-3d
  orders its factorisation by PARDISO's analysis (:func:`fem_reference._pardiso.metis_positions`).

``unpack`` (there, stdlib only) extracts every archive found into one folder under /tmp,
each once (a stamp holds the archive's size): two consecutive calls, each carrying one
archive, fill it while the machine stays warm.  ``check`` (in the kit's environment, see
``validation/bench/lent_machine.sh``) proves that gmsh and MKL load from the kit, and runs
one small PARDISO factorisation, before the benchmark is trusted with the call's minutes.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

# Distributions copied as they are installed (all pure Python: py3-none wheels).
PURE = ("scikit-fem", "meshio", "rich", "markdown-it-py", "mdurl", "pygments", "pypardiso")
# MKL's libraries in each archive (the ".so.3" of the mkl wheel's lib folder).
# Measured at xz -9: 55.8 and 38.3 MiB with AVX2 in the first; with it moved, 40.5 and 53.0.
MKL_ARCHIVES = {
    "mkl": ("rt", "core", "intel_lp64", "gnu_thread", "avx512", "vml_avx512"),
    "gmsh": ("avx2", "vml_avx2", "def", "vml_def"),
}
# glibc's own libraries: never carried (the machine's loader must use its own).
GLIBC = ("libc.so", "libm.so", "libdl.so", "libpthread.so", "librt.so", "ld-linux",
         "libresolv.so", "libutil.so", "linux-vdso")
KIT_DIR = Path("/tmp/lent-kit")


def _installed(venv: Path, dist: str) -> list[Path]:
    """The files of ``dist`` in ``venv`` below its site-packages (its dist-info included),
    bytecode left out."""
    code = ("import importlib.metadata as m, json, sys; d = m.distribution(sys.argv[1]); "
            "print(json.dumps([str(d.locate_file(f)) for f in d.files]))")
    out = subprocess.run([str(venv / "bin" / "python"), "-c", code, dist], check=True,
                         capture_output=True, text=True).stdout
    return [Path(p) for p in json.loads(out) if "__pycache__" not in p]


def _site(venv: Path) -> Path:
    code = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    return Path(subprocess.run([str(venv / "bin" / "python"), "-c", code], check=True,
                               capture_output=True, text=True).stdout.strip())


def needed_libraries(ldd_output: str) -> dict[str, str]:
    """``{soname: path}`` of the libraries ``ldd`` resolved, glibc's left out."""
    found = {}
    for line in ldd_output.splitlines():
        parts = line.split()
        if len(parts) >= 3 and parts[1] == "=>" and parts[2].startswith("/"):
            if not any(parts[0].startswith(g) for g in GLIBC):
                found[parts[0]] = parts[2]
    return found


def build(venv: Path, out: Path, level: int) -> dict:
    """Stage the kit from ``venv`` and write its two archives into ``out``; their sizes."""
    site, lib = _site(venv), venv / "lib"
    with tempfile.TemporaryDirectory() as tmp:
        stage = {name: Path(tmp) / name for name in MKL_ARCHIVES}
        py = stage["gmsh"] / "py"
        for dist in PURE:
            for f in _installed(venv, dist):
                if f.suffix in (".so", ".pyd"):
                    raise SystemExit(f"lent_kit: {dist} has a compiled file {f}: not pure "
                                     "Python, so not portable across Python versions")
                if f.is_relative_to(site) and f.is_file():
                    (py / f.relative_to(site)).parent.mkdir(parents=True, exist_ok=True)
                    shutil.copy2(f, py / f.relative_to(site))
        gmsh_lib = next(lib.glob("libgmsh.so.*"))
        shutil.copy2(site / "gmsh.py", py / "gmsh.py")
        shutil.copy2(gmsh_lib, py / gmsh_lib.name)  # gmsh.py looks beside itself first
        ldd = subprocess.run(["ldd", str(gmsh_lib)], check=True, capture_output=True,
                             text=True).stdout
        (stage["gmsh"] / "sys").mkdir()
        for soname, path in needed_libraries(ldd).items():
            if not path.startswith(str(venv)):
                shutil.copy2(path, stage["gmsh"] / "sys" / soname)
        for name, kernels in MKL_ARCHIVES.items():
            (stage[name] / "mkl").mkdir(parents=True, exist_ok=True)
            for k in kernels:
                shutil.copy2(lib / f"libmkl_{k}.so.3", stage[name] / "mkl")
        out.mkdir(parents=True, exist_ok=True)
        sizes = {}
        for name, folder in stage.items():
            archive = out / f"kit-{name}.tar.xz"
            partial = archive.with_suffix(".partial")
            with open(partial, "wb") as sink:
                tar = subprocess.Popen(["tar", "-C", str(folder), "-cf", "-", "."],
                                       stdout=subprocess.PIPE)
                subprocess.run(["xz", f"-{level}", "-T0", "-c"], stdin=tar.stdout,
                               stdout=sink, check=True)
                if tar.wait() != 0:
                    raise SystemExit(f"lent_kit: tar of {folder} failed")
            partial.replace(archive)
            sizes[archive.name] = archive.stat().st_size
    return sizes


def loadable(name: str) -> bool:
    """Whether this machine's loader finds ``name`` and all it needs without the kit."""
    try:
        ctypes.CDLL(name)
    except OSError:
        return False
    return True


def unpack(kit: Path, to: Path) -> list[str]:
    """Extract each archive of ``kit`` not yet in ``to``; drop the carried system libraries
    this machine has; the archives now unpacked in ``to``."""
    to.mkdir(parents=True, exist_ok=True)
    for archive in sorted(kit.glob("kit-*.tar.xz")):
        stamp = to / f".{archive.name}.done"
        size = str(archive.stat().st_size)
        if stamp.exists() and stamp.read_text() == size:
            print(f"lent_kit: {archive.name} already unpacked", flush=True)
            continue
        with tarfile.open(archive, "r:xz") as tar:
            tar.extractall(to, filter="data")
        stamp.write_text(size)
        print(f"lent_kit: {archive.name} unpacked into {to}", flush=True)
    system = to / "sys"
    if system.is_dir():
        for f in sorted(system.iterdir()):
            if loadable(f.name):
                f.unlink()
        print("lent_kit: system libraries carried: "
              f"{' '.join(f.name for f in sorted(system.iterdir())) or 'none'}", flush=True)
    return sorted(s.name[1:-5] for s in to.glob(".kit-*.tar.xz.done"))


def check(to: Path) -> int:
    """In the kit's environment: gmsh and MKL come from ``to``, PARDISO factorises."""
    import numpy as np
    import scipy.sparse as sp
    from threadpoolctl import threadpool_info

    import gmsh
    import meshio  # noqa: F401  (the VTU writer's import must resolve too)
    import skfem  # noqa: F401
    from fem_reference._pardiso import Pardiso, mkl_runtime_path

    n = 2000
    A = sp.diags([np.full(n - 1, -1.0), np.full(n, 4.0), np.full(n - 1, -1.0)], [-1, 0, 1],
                 format="csr")
    x = Pardiso(A).solve(np.ones(n))
    residual = float(np.linalg.norm(A @ x - 1.0) / np.sqrt(n))
    with open("/proc/self/maps") as maps:
        loaded = sorted({line.split()[-1] for line in maps
                         if "libmkl" in line or "gomp" in line or "libgmsh" in line})
    report = {"gmsh_library": gmsh.libpath, "mkl_runtime": mkl_runtime_path(),
              "pardiso_residual": residual, "loaded": loaded,
              "threadpools": [{k: i.get(k) for k in ("internal_api", "filepath", "version",
                                                     "threading_layer", "num_threads")}
                              for i in threadpool_info()]}
    print(json.dumps(report, indent=1), flush=True)
    outside = [p for p in [gmsh.libpath, mkl_runtime_path()] + [p for p in loaded if "mkl" in p]
               if not str(p).startswith(str(to))]
    if outside or not residual < 1e-12:
        print(f"lent_kit: not from the kit {outside} or PARDISO residual {residual:.1e}",
              file=sys.stderr)
        return 1
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.lent_kit", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="step", required=True)
    b = sub.add_parser("build", help="pack the kit here")
    b.add_argument("--venv", type=Path, default=Path(".venv"))
    b.add_argument("--out", type=Path, default=Path(".lent"))
    b.add_argument("--level", type=int, default=9, choices=range(10), metavar="0-9",
                   help="xz preset (default 9)")
    u = sub.add_parser("unpack", help="extract the archives found (there)")
    u.add_argument("--kit", type=Path, default=Path(".lent"))
    u.add_argument("--to", type=Path, default=KIT_DIR)
    c = sub.add_parser("check", help="gmsh and MKL from the kit, one PARDISO solve")
    c.add_argument("--to", type=Path, default=KIT_DIR)
    args = ap.parse_args(argv)
    if args.step == "build":
        for name, size in build(args.venv, args.out, args.level).items():
            print(f"{args.out / name}: {size / 2**20:.1f} MiB")
        return 0
    if args.step == "unpack":
        print(f"lent_kit: unpacked: {' '.join(unpack(args.kit, args.to)) or 'nothing'}")
        return 0
    return check(args.to)


if __name__ == "__main__":
    sys.exit(main())
