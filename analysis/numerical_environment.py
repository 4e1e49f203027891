"""The numerical environment that a run's floating-point results depend on.

Episode records are replayed bit for bit (``tests/analysis/test_table3_records.py``,
``test_table4_records.py``). Most methods' records replay on any x86-64 CPU, but TEB's
do not: its L-BFGS-B iterations amplify differences in the last bit of BLAS results into
different trajectories, and OpenBLAS chooses its kernels by CPU at run time (measured in
``benchmarks/blas_kernel_sensitivity.py``: the same TEB episodes under OpenBLAS's
Haswell, Sandybridge and Nehalem kernels). The same holds, in principle, for numpy's
SIMD loops, which dispatch on the CPU's features.

The records are therefore made and replayed under `RECORDS_ENVIRONMENT`: OpenBLAS's
Haswell kernels (x86-64 with AVX2 and FMA, so every CPU of that level or above runs the
same code) and numpy's dispatch capped below AVX-512. This is the analogue of MKL's
``MKL_CBWR`` ("conditional numerical reproducibility"). Both variables are read when the
libraries load, so they must be in the environment before the process imports numpy:
``RECORDS_ENVIRONMENT`` is meant for a child process's environment or the shell, and
this module never changes its own process's. `numerical_environment` reports what a
process actually runs with, so that a run can show (and a test can check) that the pin
took effect.
"""

from __future__ import annotations

import ctypes
import glob
import importlib
import os
import platform
from collections.abc import Iterator, Mapping

__all__ = ["RECORDS_ENVIRONMENT", "RECORDS_BLAS_KERNEL", "blas_kernels", "numerical_environment"]

#: The OpenBLAS kernel the committed records are made and replayed with.
RECORDS_BLAS_KERNEL = "Haswell"


class _Variables(Mapping[str, str]):
    """Environment variables under which the committed records are made and replayed (read-only).

    Apply them to a child process (``{**os.environ, **RECORDS_ENVIRONMENT}``) or prefix a
    shell command with them; they act when numpy and scipy load their libraries.
    """

    def __init__(self, variables: Mapping[str, str]) -> None:
        self._variables = dict(variables)

    def __getitem__(self, name: str) -> str:
        return self._variables[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._variables)

    def __len__(self) -> int:
        return len(self._variables)

    def __repr__(self) -> str:
        return f"RECORDS_ENVIRONMENT({self._variables!r})"


RECORDS_ENVIRONMENT: Mapping[str, str] = _Variables(
    {
        "OPENBLAS_CORETYPE": RECORDS_BLAS_KERNEL,
        # numpy >= 2.4 names its AVX-512 dispatch targets by these groups; a name the CPU
        # lacks is ignored, so the same value serves AVX2-only and AVX-512 machines.
        "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
        "OPENBLAS_NUM_THREADS": "1",
    }
)

# OpenBLAS builds bundled by numpy and scipy wheels (scipy-openblas), and their exported
# "which kernel did you choose" functions.
_OPENBLAS_LIBRARIES = (
    ("numpy", "numpy.libs/libscipy_openblas64_*.so*", "scipy_openblas_get_corename64_"),
    ("scipy", "scipy.libs/libscipy_openblas-*.so*", "scipy_openblas_get_corename"),
)


def blas_kernels() -> dict[str, str | None]:
    """The OpenBLAS kernel (core name) that numpy's and scipy's bundled OpenBLAS run.

    Importing numpy and scipy loads their libraries, so the answer is the kernel of this
    process. A library that is not a bundled OpenBLAS (a system BLAS, MKL, another
    platform's wheel) is reported as None.

    Returns
    -------
    dict
        ``{"numpy": name or None, "scipy": name or None}``, e.g. ``"Haswell"``.
    """
    import numpy
    import scipy.linalg  # noqa: F401  (loads scipy's BLAS)

    site = os.path.dirname(os.path.dirname(numpy.__file__))
    kernels: dict[str, str | None] = {}
    for package, pattern, function in _OPENBLAS_LIBRARIES:
        kernels[package] = None
        for path in sorted(glob.glob(os.path.join(site, pattern))):
            # the library is already loaded: dlopen returns the same handle
            query = getattr(ctypes.CDLL(path), function, None)
            if query is not None:
                query.restype = ctypes.c_char_p
                name = query()
                kernels[package] = name.decode() if name else None
                break
    return kernels


def numerical_environment() -> dict:
    """What this process's floating-point results depend on, as a JSON-ready dict.

    Returns
    -------
    dict
        ``machine`` (``platform.machine()``), ``cpu`` (the model name, where
        ``/proc/cpuinfo`` tells), ``numpy`` and ``scipy`` (versions),
        ``numpy_simd_targets`` (the dispatch targets numpy found and uses, capped by
        ``NPY_DISABLE_CPU_FEATURES``), ``blas_kernels`` (`blas_kernels`), and
        ``pinned`` (the `RECORDS_ENVIRONMENT` variables as this process has them, None
        where unset) and ``matches_records`` (whether they equal `RECORDS_ENVIRONMENT`,
        both BLAS kernels are `RECORDS_BLAS_KERNEL` and numpy uses no AVX-512 target).
    """
    import numpy
    import scipy

    try:
        umath = importlib.import_module("numpy._core._multiarray_umath")
    except ImportError:  # numpy < 2
        umath = importlib.import_module("numpy.core._multiarray_umath")
    features = umath.__cpu_features__
    targets = [name for name in umath.__cpu_dispatch__ if features.get(name)]
    kernels = blas_kernels()
    pinned = {name: os.environ.get(name) for name in RECORDS_ENVIRONMENT}
    return {
        "machine": platform.machine(),
        "cpu": _cpu_model(),
        "numpy": numpy.__version__,
        "scipy": scipy.__version__,
        "numpy_simd_targets": targets,
        "blas_kernels": kernels,
        "pinned": pinned,
        "matches_records": _matches_records(pinned, kernels, targets),
    }


def _matches_records(pinned: Mapping[str, str | None], kernels: Mapping[str, str | None], targets: list[str]) -> bool:
    """The variables as pinned, both BLAS kernels the records', and no AVX-512 loop in use.

    The last is checked on what numpy reports, not on the variable: numpy releases before
    2.4 name their AVX-512 targets differently (``AVX512F``, ``AVX512_SKX``, ...), and
    there the variable would cap nothing.
    """
    return (
        dict(pinned) == dict(RECORDS_ENVIRONMENT)
        and all(kernel == RECORDS_BLAS_KERNEL for kernel in kernels.values())
        and not any(name.startswith(("AVX512", "X86_V4")) for name in targets)
    )


def _cpu_model() -> str | None:
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None
