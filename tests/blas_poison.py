"""Pack everything that feeds a run while BLAS and LAPACK cannot be called (issue 32).

Run as a script (``tests/test_cpu_independence.py`` does, in a subprocess of its own):

    python tests/blas_poison.py pack              # every shipped campaign, vehicle and mission
    python tests/blas_poison.py control 'CODE'    # CODE must not get through (the detector's check)

Two layers, so that BLAS or LAPACK creeping into what feeds a run fails on any machine, not
only on one whose kernels happen to round differently:

1. the Python entry points raise: every function of ``numpy.linalg`` and ``scipy.linalg``,
   ``np.dot``, ``np.matmul``, ``np.inner``, ``np.vdot``, ``np.tensordot``, ``np.einsum`` (its
   sum-of-products loops are SIMD code chosen per CPU), ``np.kron`` on floating-point operands
   (integer ones are numpy's exact loops);
2. the machine code: the first bytes of every BLAS/LAPACK function that the loaded OpenBLAS
   libraries export (numpy's and scipy's: ``cblas_*``, ``LAPACKE_*`` and the Fortran names such
   as ``dgemm_``, ``dgesdd_``, with OpenBLAS's ``scipy_`` and ``64_`` affixes) are overwritten
   with an illegal instruction. This is what catches ``a @ b`` on float arrays and
   ``ndarray.dot``, which no monkeypatch reaches (the operator goes straight from the C type to
   the matmul loop and on to ``cblas_dgemm``/``cblas_dgemv``/``cblas_ddot``), and anything
   imported as ``from numpy.linalg import pinv`` before layer 1. The process then dies of
   SIGILL, and faulthandler prints the Python line that called it.

numpy's own loops (elementwise ufuncs, reductions, ``np.cross``) are not BLAS and stay usable. Not
covered: a BLAS other than a loaded library ``lib*blas*`` or ``lib*lapack*``, and
code paths no shipped campaign takes.
"""

import ctypes
import faulthandler
import mmap
import os
import platform
import re
import struct
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TRAP = {"x86_64": b"\x0f\x0b", "AMD64": b"\x0f\x0b", "aarch64": b"\x00\x00\x00\x00"}  # ud2; udf #0
# the public BLAS/LAPACK names, after OpenBLAS's optional "scipy_" prefix and "64_" suffix
PUBLIC = re.compile(r"^(?:scipy_)?(?:cblas_\w+|LAPACKE_\w+|i?[sdczx][a-z0-9]{2,}_(?:64_)?)$")
NUMPY_ENTRY_POINTS = ("dot", "matmul", "inner", "vdot", "tensordot", "einsum", "kron")
# look-ups that scipy's modules make on import; what they return is poisoned by layer 2
LOOKUPS = ("get_blas_funcs", "get_lapack_funcs", "find_best_blas_type")


class BlasCalled(AssertionError):
    pass


def _raiser(name, original=None):
    """An entry point that raises; with ``original``, only for floating-point operands (numpy's
    integer products are its own exact loops: scipy's Sobol' scrambling takes one)."""

    def entry_point(*args, **kwargs):
        import numpy as np

        floating = any(np.issubdtype(np.asarray(a).dtype, np.inexact) for a in args if not isinstance(a, str))
        if original is not None and not floating:
            return original(*args, **kwargs)
        raise BlasCalled(f"{name} called while packing: BLAS/LAPACK must not feed a run")

    return entry_point


def poison_python_entry_points():
    """Layer 1: the numpy and scipy functions that reach BLAS or LAPACK raise."""
    import numpy as np
    import scipy.linalg

    for module, prefix in ((np.linalg, "np.linalg"), (scipy.linalg, "scipy.linalg")):
        for name in dir(module):
            value = getattr(module, name)
            if callable(value) and not isinstance(value, type) and not name.startswith("_") and name not in LOOKUPS:
                setattr(module, name, _raiser(f"{prefix}.{name}"))
    for name in NUMPY_ENTRY_POINTS:
        setattr(np, name, _raiser(f"np.{name}", getattr(np, name)))


def _exported_functions(path):
    """Names of the functions an ELF64 shared library defines in its dynamic symbol table."""
    data = Path(path).read_bytes()
    (shoff,) = struct.unpack_from("<Q", data, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", data, shoff + i * shentsize) for i in range(shnum)]
    names = []
    for _name, kind, _flags, _addr, offset, size, link, _info, _align, entsize in sections:
        if kind != 11:  # SHT_DYNSYM
            continue
        strings = sections[link][4]
        for at in range(offset, offset + size, entsize):
            st_name, st_info, _other, st_shndx, _value, _size = struct.unpack_from("<IBBHQQ", data, at)
            if st_info & 0xF == 2 and st_shndx != 0:  # STT_FUNC, defined here
                end = data.index(b"\0", strings + st_name)
                names.append(data[strings + st_name : end].decode())
    return names


def _blas_libraries():
    """Paths of the loaded shared libraries whose file name says BLAS or LAPACK."""
    paths = set()
    for line in Path("/proc/self/maps").read_text().splitlines():
        parts = line.split(maxsplit=5)
        if len(parts) == 6 and re.match(r"lib.*(blas|lapack)", Path(parts[5]).name, re.IGNORECASE):
            paths.add(parts[5])
    return sorted(paths)


def poison_machine_code():
    """Layer 2: every public BLAS/LAPACK function of the loaded libraries starts with a trap.
    Returns {library file name: number of functions poisoned}."""
    trap = TRAP[platform.machine()]
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mprotect.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int)
    page = mmap.PAGESIZE
    done = {}
    for path in _blas_libraries():
        library = ctypes.CDLL(path)
        count = 0
        for name in _exported_functions(path):
            if not PUBLIC.match(name):
                continue
            address = ctypes.cast(getattr(library, name), ctypes.c_void_p).value
            start = address - address % page
            length = address + len(trap) - start
            # writable (not executable) while written, then executable again: W^X policies allow it
            if libc.mprotect(start, length, mmap.PROT_READ | mmap.PROT_WRITE) != 0:
                raise OSError(ctypes.get_errno(), f"mprotect {path}")
            ctypes.memmove(address, trap, len(trap))
            if libc.mprotect(start, length, mmap.PROT_READ | mmap.PROT_EXEC) != 0:
                raise OSError(ctypes.get_errno(), f"mprotect {path}")
            count += 1
        done[Path(path).name] = count
    return done


def poison():
    """Both layers; numpy's and scipy's BLAS loaded first (scipy.linalg loads scipy's own)."""
    import numpy as np
    import scipy.linalg  # noqa: F401 - loads scipy's OpenBLAS, so that it is poisoned too

    np.ones((2, 2)) @ np.ones((2, 2))  # any one-time set-up of the BLAS happens before the trap
    faulthandler.enable()  # SIGILL: the Python traceback of the call, on stderr
    poisoned = poison_machine_code()
    if not poisoned or min(poisoned.values()) < 10:
        raise AssertionError(f"expected the BLAS libraries' functions poisoned, got {poisoned}")
    poison_python_entry_points()
    return poisoned


def shipped_pairs():
    """(vehicle file, mission file) of every vehicle and mission shipped in configs/ that no
    campaign flies, with a partner of its family."""
    return [
        ("configs/vehicles/refex-table2-fall.yaml", "configs/missions/refex-exo.yaml"),
        ("configs/vehicles/irassi.yaml", "configs/missions/irassi-large-angle.yaml"),
    ]


def _point_campaigns(campaign):
    from refexmc.config import sweep

    if "sweep" not in campaign:
        return [campaign]
    return [sweep.point_campaign(campaign, i, values) for i, values in enumerate(sweep.points(campaign))]


def pack_everything(runs_per_campaign=40):
    """Everything that feeds a run, for every shipped campaign (each sweep point): the nominal
    inputs, the draws and inputs of its first runs (failure sets included), the wheel tables with
    every set of one or two wheels failed and detected; and every shipped vehicle and mission
    file, packed. Returns {what: number of runs or packs}."""
    import itertools

    import yaml

    from refexmc.campaign.chunk import RunPlan, plan_for
    from refexmc.config import derived
    from refexmc.config.load import load_campaign, load_mission, load_vehicle
    from refexmc.config.pack import pack

    packed, covered = {}, set()
    for path in sorted((ROOT / "campaigns").glob("*.yaml")):
        raw = yaml.safe_load(path.read_text())
        covered |= {(path.parent / raw[part]).resolve() for part in ("vehicle", "mission")}
        campaign = load_campaign(path)
        for point in _point_campaigns(campaign):
            plan = plan_for(point)
            prepared = plan.prepare_runs(list(range(min(point["runs"], runs_per_campaign))))
            errors = [p for p in prepared if isinstance(p, Exception)]
            if errors:  # a run whose preparation raised (BlasCalled, say): shown with its traceback
                raise errors[0]
            packed[point["name"]] = len(prepared)
            if isinstance(plan, RunPlan) and derived.wheel_count(point["vehicle"]):
                n = derived.wheel_count(point["vehicle"])
                for failed in (s for k in (1, 2) for s in itertools.combinations(range(1, n + 1), k)):
                    pack(point["vehicle"], point["mission"], failed_wheels=failed, detected_wheels=failed)
                    packed[f"{point['name']} wheels {failed} detected"] = 1
    for vehicle_file, mission_file in shipped_pairs():
        pack(load_vehicle(ROOT / vehicle_file), load_mission(ROOT / mission_file))
        packed[f"{vehicle_file} + {mission_file}"] = 1
        covered |= {(ROOT / vehicle_file).resolve(), (ROOT / mission_file).resolve()}
    shipped = {path.resolve() for part in ("vehicles", "missions") for path in (ROOT / "configs" / part).glob("*.yaml")}
    if shipped - covered:
        raise AssertionError(f"shipped files no campaign or shipped_pairs() packs: {sorted(shipped - covered)}")
    return packed


if __name__ == "__main__":
    os.chdir(ROOT)
    poisoned = poison()
    if sys.argv[1] == "control":
        import numpy as np  # noqa: F401 - for the control's code

        exec(sys.argv[2])  # noqa: S102 - the test's own one-liner
        print("CONTROL GOT THROUGH")
    else:
        print(poisoned, pack_everything())
