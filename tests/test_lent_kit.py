"""The lent machine's fem-3d kit (validation.bench.lent_kit): what it carries of gmsh's
system libraries, and its unpacking, once per archive, keeping only the libraries the
machine cannot load itself."""

from __future__ import annotations

import io
import tarfile

from validation.bench import lent_kit

LDD = """\
\tlinux-vdso.so.1 (0x00007f3926b7f000)
\tlibGLU.so.1 => /lib/x86_64-linux-gnu/libGLU.so.1 (0x00007f3920d6e000)
\tlibm.so.6 => /lib/x86_64-linux-gnu/libm.so.6 (0x00007f3920a2a000)
\tlibgomp.so.1 => /lib/x86_64-linux-gnu/libgomp.so.1 (0x00007f3920798000)
\tlibc.so.6 => /lib/x86_64-linux-gnu/libc.so.6 (0x00007f39205b6000)
\t/lib64/ld-linux-x86-64.so.2 (0x00007f3926b81000)
\tlibmissing.so.2 => not found
"""


def test_needed_libraries_leave_glibc_out():
    assert lent_kit.needed_libraries(LDD) == {
        "libGLU.so.1": "/lib/x86_64-linux-gnu/libGLU.so.1",
        "libgomp.so.1": "/lib/x86_64-linux-gnu/libgomp.so.1"}


def _archive(path, files):
    with tarfile.open(path, "w:xz") as tar:
        for name, data in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))


def test_unpack_once_per_archive_and_keep_only_missing_libraries(tmp_path):
    kit, to = tmp_path / "kit", tmp_path / "to"
    kit.mkdir()
    # libm.so.6: this machine's loader has it; the other name no machine has.
    _archive(kit / "kit-gmsh.tar.xz", {"py/mod.py": b"x = 1\n", "sys/libm.so.6": b"",
                                       "sys/libpillar-xval-absent.so.1": b""})
    assert lent_kit.unpack(kit, to) == ["kit-gmsh.tar.xz"]
    assert (to / "py" / "mod.py").read_text() == "x = 1\n"
    assert sorted(p.name for p in (to / "sys").iterdir()) == ["libpillar-xval-absent.so.1"]
    (to / "py" / "mod.py").write_text("changed")
    _archive(kit / "kit-mkl.tar.xz", {"mkl/libmkl_rt.so.3": b"rt"})
    assert lent_kit.unpack(kit, to) == ["kit-gmsh.tar.xz", "kit-mkl.tar.xz"]
    assert (to / "py" / "mod.py").read_text() == "changed"  # not unpacked twice
    assert (to / "mkl" / "libmkl_rt.so.3").read_bytes() == b"rt"
