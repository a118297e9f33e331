"""Pinned CPU code paths: the same floating-point result across x86-64 machines where it holds.

NumPy, OpenBLAS (NumPy's and SciPy's BLAS/LAPACK), MKL (torch's BLAS/LAPACK), oneDNN
and torch's own vectorised kernels each pick, at run time, the fastest code for the CPU
they run on (AVX-512 on one machine, AVX2 on another). Those code paths sum in a
different order, so the last bits of a result differ; a Bayesian-optimisation loop
then evaluates slightly different points, and the printed posterior can change in its
last digit from one machine to another (measured, README "Set-up"). Measured on one
Intel Xeon (AVX-512), each library alone changes the bits of a small calibration or of
the measured spectra when its code path is switched (session 9, README).

:func:`pin_code_paths` sets, before those libraries load, the environment variables that
fix each library's path to one that every x86-64 CPU with AVX2 and FMA (x86-64-v3: Intel
since 2013, AMD since 2015) runs identically:

=============================  ===============  ======================================
variable                       value            library
=============================  ===============  ======================================
``ATEN_CPU_CAPABILITY``        ``avx2``         torch's vectorised kernels
``MKL_CBWR``                   ``COMPATIBLE``   MKL (torch's BLAS/LAPACK): conditional
                                                numerical reproducibility, one code
                                                path on Intel and AMD
``ONEDNN_MAX_CPU_ISA``         ``AVX2``         oneDNN (torch)
``OPENBLAS_CORETYPE``          ``Haswell``      OpenBLAS (NumPy's and SciPy's)
``NPY_DISABLE_CPU_FEATURES``   AVX-512 targets  NumPy's dispatched kernels (only where
                                                the CPU has AVX-512; the names depend
                                                on the NumPy version)
=============================  ===============  ======================================

``import susp_bo`` calls it (the ``susp-bo`` command always imports it first, and so do
Dask workers, which inherit the environment). A value already set in the environment is
kept; ``SUSP_BO_NATIVE_NUMERICS=1`` turns the pinning off (the libraries' own choice:
faster on some CPUs, machine-dependent last bits). A program that imports NumPy or
torch *before* susp_bo loads them unpinned: :func:`numerics_in_effect` says what is in
effect, and ``result.json["numerics"]`` records it with every result.

What is not covered: other CPU families (ARM, POWER: nothing is pinned there), CPUs
without AVX2, and the C library's scalar ``exp``/``log`` (the same within one Linux
distribution release; may differ between distributions). Measured: bit-identical
results between two Intel Xeons of one model (session 10), but **not** between an Intel
Xeon and an AMD EPYC (Zen 3, session 17: the demo's draws differ in their last bits, the
verdict and printed figures agree to about the last digit; README "Set-up"); so
``machine_independent`` means "every pin holds", not "identical on every CPU". The code
path that still differs was not found. Session 18 found no dispatch keyed on the CPU's
vendor as far as it could look: under QEMU user-mode emulation with an Intel and an AMD
CPUID, the demo's 120 design spectra (also equal to the native AMD run's) and its first
batch of new points came out bit-identical. The emulation cannot follow the run further:
its floating point is not the hardware's (torch's square root of the GP's first distance
matrix differed from the native CPU's in 212 of 1 600 last bits). Left as suspects: a
kernel keyed on AVX-512 that the pins do not reach (the Intel Xeon has AVX-512, the AMD
EPYC not). What such a last-bit difference does to a result is measured by
``benchmarks/last_bit_sensitivity.py`` (README "Set-up").

The thread count is the other source of last-bit differences on one machine: a BLAS
product splits its work between threads differently for each count. :func:`one_blas_thread`
runs a block on one BLAS thread; the simulator's sensor products and band average, the
local phase's model and the paired likelihood run in it (session 18: before, the demo's
data and a worker's spectra depended on the core count and on whether the program had
imported NumPy before the worker pool started). Since session 19 the whole of
:func:`~susp_bo.calibration.loop.calibrate` and :func:`~susp_bo.calibration.study.run_study`
runs in it too (the main process's log L, surrogate and chains: a 16-core machine splits
their products in other pieces than a 2-core one may); and the limit holds while any
thread is inside such a block (before, the first block to end restored many threads under
a block still running in another thread, and threadpoolctl silently ignored a change made
from any thread but the one that first made one).
"""

from __future__ import annotations

import os
import platform
import sys
import threading
from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
from functools import lru_cache
from importlib import metadata
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    from threadpoolctl import ThreadpoolController

OPT_OUT = "SUSP_BO_NATIVE_NUMERICS"
"""Environment variable: ``1`` leaves every library's code path to the library."""

NUMPY_SWITCH = "NPY_DISABLE_CPU_FEATURES"
"""Environment variable listing NumPy's dispatch targets to leave unused."""

PINNED_CODE_PATHS: dict[str, str] = {
    "ATEN_CPU_CAPABILITY": "avx2",
    "MKL_CBWR": "COMPATIBLE",
    "ONEDNN_MAX_CPU_ISA": "AVX2",
    "OPENBLAS_CORETYPE": "Haswell",
}
"""The library switches set on every x86-64-v3 CPU (module docstring)."""

_X86 = {"x86_64", "amd64"}


def numpy_avx512_targets(numpy_version: str) -> str:
    """NumPy's dispatch-target names above AVX2 for ``numpy_version`` (space separated).

    NumPy 2.4 groups its x86 targets as X86_V2/V3/V4 plus AVX512_ICL/SPR; earlier
    versions name each AVX-512 family. Unknown names are ignored by NumPy 2.4.
    """
    major, minor = (int(part) for part in numpy_version.split(".")[:2])
    if (major, minor) >= (2, 4):
        return "X86_V4 AVX512_ICL AVX512_SPR"
    return "AVX512F AVX512CD AVX512_KNL AVX512_KNM AVX512_SKX AVX512_CLX AVX512_CNL " + (
        "AVX512_ICL AVX512_SPR"
    )


def cpu_flags() -> frozenset[str] | None:
    """The CPU's feature flags from ``/proc/cpuinfo`` (Linux), None where unknown."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as handle:
            for line in handle:
                if line.startswith("flags"):
                    return frozenset(line.split(":", 1)[1].split())
    except OSError:
        return None
    return None


def pin_code_paths(
    environ: MutableMapping[str, str] | None = None,
    *,
    machine: str | None = None,
    flags: frozenset[str] | Literal["detect"] | None = "detect",
    numpy_version: str | None = None,
) -> dict[str, str]:
    """Set the pinned code paths in ``environ`` where they are not set; return what was set.

    Nothing is set when ``SUSP_BO_NATIVE_NUMERICS=1``, on a CPU that is not x86-64, or
    where the CPU's flags are unknown or lack AVX2 or FMA.

    Args:
        environ: the environment to change (default: ``os.environ``, which child
            processes inherit).
        machine: ``platform.machine()`` (default: this machine's).
        flags: the CPU's feature flags, None where unknown (default ``"detect"``:
            :func:`cpu_flags`).
        numpy_version: the installed NumPy's version (default: read from its metadata,
            without importing it).
    """
    env = os.environ if environ is None else environ
    if env.get(OPT_OUT, "") == "1":
        return {}
    if (machine if machine is not None else platform.machine()).lower() not in _X86:
        return {}
    if flags == "detect":
        flags = cpu_flags()
    if flags is None or not {"avx2", "fma"} <= flags:
        return {}
    wanted = dict(PINNED_CODE_PATHS)
    if "avx512f" in flags:
        if numpy_version is None:
            try:
                numpy_version = metadata.version("numpy")
            except metadata.PackageNotFoundError:
                numpy_version = None
        if numpy_version is not None:
            wanted[NUMPY_SWITCH] = numpy_avx512_targets(numpy_version)
    applied = {}
    for name, value in wanted.items():
        if name not in env:
            env[name] = value
            applied[name] = value
    return applied


def numerics_in_effect() -> dict[str, Any]:
    """What the numerical libraries actually run with (imports NumPy and torch).

    Returns ``{"machine_independent": bool, "torch_cpu_capability": str,
    "numpy_simd_above_avx2": [names], "openblas_core": [names], "environment":
    {variable: value or None}}``; ``machine_independent`` is true when every pinned code
    path is in effect (see the module docstring for what that does not cover).
    """
    import numpy as np
    import torch
    from threadpoolctl import threadpool_info

    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # NumPy < 2
        from numpy.core._multiarray_umath import (  # type: ignore[no-redef]
            __cpu_dispatch__,
            __cpu_features__,
        )
    high = [
        name
        for name in __cpu_dispatch__
        if __cpu_features__.get(name) and ("AVX512" in name or name == "X86_V4")
    ]
    cores = sorted({
        str(pool.get("architecture"))
        for pool in threadpool_info()
        if pool.get("internal_api") == "openblas"
    })  # fmt: skip
    capability = str(torch.backends.cpu.get_cpu_capability())
    variables = [*PINNED_CODE_PATHS, NUMPY_SWITCH, OPT_OUT]
    environment = {name: os.environ.get(name) for name in variables}
    pinned = (
        capability == "AVX2"
        and not high
        and all(core.lower() == "haswell" for core in cores)
        and all(os.environ.get(k) == v for k, v in PINNED_CODE_PATHS.items())
    )
    return {
        "machine_independent": bool(pinned),
        "torch_cpu_capability": capability,
        "numpy_simd_above_avx2": high,
        "openblas_core": cores,
        "numpy": np.__version__,
        "torch": torch.__version__,
        "environment": environment,
    }


_BLAS_CARRIERS = ("numpy", "scipy.linalg")
"""Modules whose import loads a BLAS library of its own (NumPy's, SciPy's OpenBLAS)."""


@lru_cache(maxsize=4)
def _blas_controller(loaded: tuple[bool, ...]) -> ThreadpoolController:
    """The BLAS libraries loaded, found once per set of ``loaded`` carriers (a fresh
    lookup costs milliseconds; a carrier imported later gets a new lookup)."""
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


class _OneBlasThread:
    """Process-wide state of :func:`one_blas_thread`: how many blocks are inside, and the
    limiter that restores the thread counts when the last one leaves.

    BLAS thread counts are global to the process, so blocks entered by several threads
    (a Dask worker runs tasks in threads of one process) share one limit: the first block
    in sets it, the last block out restores it. Without the count, a block that ends
    while another thread's block still runs would restore many threads under it.
    threadpoolctl (≥ 3.6) lets only one thread at a time change OpenBLAS's pthreads pool
    and silently ignores the others; each change here is made under this lock with that
    ownership taken and handed back, so it takes effect from whichever thread makes it.
    """

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.depth = 0
        self.limiter: Any = None

    def enter(self) -> None:
        with self.lock:
            if self.depth == 0:
                loaded = tuple(name in sys.modules for name in _BLAS_CARRIERS)
                controller = _blas_controller(loaded)
                with _openblas_ownership():
                    self.limiter = controller.limit(limits=1, user_api="blas")
            self.depth += 1

    def leave(self) -> None:
        with self.lock:
            self.depth -= 1
            if self.depth == 0:
                with _openblas_ownership():
                    self.limiter.restore_original_limits()
                self.limiter = None


@contextmanager
def _openblas_ownership() -> Iterator[None]:
    """The calling thread may change OpenBLAS's thread count in the block (threadpoolctl
    hands that right to one thread at a time); nobody holds it afterwards."""
    from threadpoolctl import OpenBLASController

    clear = getattr(OpenBLASController, "clear_controlling_thread", None)  # threadpoolctl ≥ 3.6
    if clear is None:
        yield
        return
    clear(force=True)
    try:
        yield
    finally:
        clear(force=True)


_ONE_BLAS_THREAD = _OneBlasThread()


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Context: the BLAS libraries loaded so far run on one thread in the block.

    A BLAS product splits its work between threads differently for each thread count,
    and the split changes the last bits of some results (measured: 1–3 of 480 values of a
    PyBullet run's spectra differ by one unit in the last place between one and two
    OpenBLAS threads). What must not depend on the machine's core count or on how the
    process was started (a simulator evaluation, the paired likelihood, the discrepancy
    workflow's solves) runs in here. Safe to nest and to enter from several threads at
    once (the limit holds until the last block leaves). The libraries are looked up at
    the first call, and again once SciPy's linear algebra has been imported.
    """
    _ONE_BLAS_THREAD.enter()
    try:
        yield
    finally:
        _ONE_BLAS_THREAD.leave()
