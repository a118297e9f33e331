"""Pinned CPU code paths (susp_bo.numerics): what is set where, and that it takes effect."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator

import pytest

from susp_bo.numerics import (
    OPT_OUT,
    PINNED_CODE_PATHS,
    cpu_flags,
    numpy_avx512_targets,
    one_blas_thread,
    pin_code_paths,
)

AVX512_CPU = frozenset({"sse2", "avx", "avx2", "fma", "avx512f", "avx512bw"})
AVX2_CPU = frozenset({"sse2", "avx", "avx2", "fma"})


def test_an_avx512_cpu_gets_every_pin_including_numpys() -> None:
    env: dict[str, str] = {}
    applied = pin_code_paths(env, machine="x86_64", flags=AVX512_CPU, numpy_version="2.4.6")
    assert applied == env
    assert {k: env[k] for k in PINNED_CODE_PATHS} == PINNED_CODE_PATHS
    assert env["NPY_DISABLE_CPU_FEATURES"] == "X86_V4 AVX512_ICL AVX512_SPR"


def test_an_avx2_cpu_leaves_numpy_alone() -> None:
    env: dict[str, str] = {}
    pin_code_paths(env, machine="AMD64", flags=AVX2_CPU, numpy_version="2.4.6")
    assert set(env) == set(PINNED_CODE_PATHS)


def test_values_already_in_the_environment_are_kept() -> None:
    env = {"MKL_CBWR": "AVX2", "PATH": "/bin"}
    applied = pin_code_paths(env, machine="x86_64", flags=AVX2_CPU)
    assert env["MKL_CBWR"] == "AVX2"
    assert "MKL_CBWR" not in applied
    assert env["OPENBLAS_CORETYPE"] == "Haswell"


@pytest.mark.parametrize(
    ("env", "machine", "flags"),
    [
        ({OPT_OUT: "1"}, "x86_64", AVX512_CPU),  # opted out
        ({}, "arm64", AVX512_CPU),  # not x86-64
        ({}, "aarch64", None),
        ({}, "x86_64", None),  # flags unknown
        ({}, "x86_64", frozenset({"sse2", "avx"})),  # no AVX2
        ({}, "x86_64", frozenset({"avx2"})),  # no FMA
    ],
)
def test_nothing_is_pinned_where_the_pins_do_not_apply(
    env: dict[str, str], machine: str, flags: frozenset[str] | None
) -> None:
    before = dict(env)
    assert pin_code_paths(env, machine=machine, flags=flags) == {}
    assert env == before


def test_numpy_target_names_follow_the_numpy_version() -> None:
    assert numpy_avx512_targets("2.4.0") == "X86_V4 AVX512_ICL AVX512_SPR"
    for old in ("1.26.4", "2.3.5"):
        names = numpy_avx512_targets(old).split()
        assert "AVX512_SKX" in names and "AVX512F" in names and "X86_V4" not in names


def _in_effect(extra_env: dict[str, str], first: str = "import susp_bo") -> dict:
    """numerics_in_effect() of a fresh interpreter (``first`` runs before anything else)."""
    env = {k: v for k, v in os.environ.items() if k not in PINNED_CODE_PATHS}
    env.pop("NPY_DISABLE_CPU_FEATURES", None)
    env.pop(OPT_OUT, None)
    env.update(extra_env)
    code = (
        f"{first}\nimport json\nfrom susp_bo.numerics import numerics_in_effect\n"
        "print(json.dumps(numerics_in_effect()))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout)


flags = cpu_flags()
x86_v3 = flags is not None and {"avx2", "fma"} <= flags


@pytest.mark.skipif(not x86_v3, reason="the pins apply to x86-64 CPUs with AVX2 and FMA")
def test_importing_susp_bo_first_pins_every_library() -> None:
    numerics = _in_effect({})
    assert numerics["machine_independent"] is True
    assert numerics["torch_cpu_capability"] == "AVX2"
    assert numerics["numpy_simd_above_avx2"] == []
    assert numerics["openblas_core"] == ["Haswell"]


@pytest.mark.skipif(
    flags is None or "avx512f" not in flags, reason="needs a CPU with AVX-512 to tell"
)
def test_opting_out_or_importing_numpy_first_is_reported() -> None:
    native = _in_effect({OPT_OUT: "1"})
    assert native["machine_independent"] is False
    assert native["torch_cpu_capability"] != "AVX2"
    late = _in_effect({}, first="import numpy\nimport susp_bo")
    assert late["machine_independent"] is False  # NumPy loaded unpinned: said so
    assert late["numpy_simd_above_avx2"]


@pytest.mark.skipif(not x86_v3, reason="the pins apply to x86-64 CPUs with AVX2 and FMA")
def test_the_test_suite_runs_with_the_command_lines_numerics() -> None:
    # pyproject's "-p susp_bo.numerics" imports susp_bo before any test module loads NumPy
    from susp_bo.numerics import numerics_in_effect

    assert numerics_in_effect()["machine_independent"] is True


@pytest.fixture
def two_blas_threads(blas_thread_counts: Callable[[], set[int]]) -> Iterator[None]:
    """BLAS on two threads around the test (skips where the libraries will not take 2)."""
    import numpy  # noqa: F401  (its BLAS must be loaded to be limited)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=2, user_api="blas"):
        if blas_thread_counts() != {2}:
            pytest.skip("needs a BLAS that runs on 2 threads here")
        yield


def test_one_blas_thread_holds_until_the_last_of_two_threads_leaves(
    two_blas_threads: None, blas_thread_counts: Callable[[], set[int]]
) -> None:
    # A Dask worker runs tasks in threads of one process; BLAS thread counts are global.
    # Thread a enters, b enters, a leaves: b must still run on one thread.
    a_inside, b_inside, a_left, b_checked = (threading.Event() for _ in range(4))
    seen: dict[str, set[int]] = {}

    def a() -> None:
        with one_blas_thread():
            a_inside.set()
            b_inside.wait(10)
        a_left.set()

    def b() -> None:
        a_inside.wait(10)
        with one_blas_thread():
            b_inside.set()
            a_left.wait(10)
            seen["b after a left"] = blas_thread_counts()
        b_checked.set()

    threads = [threading.Thread(target=a), threading.Thread(target=b)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(20)
    assert b_checked.is_set()
    assert seen["b after a left"] == {1}
    assert blas_thread_counts() == {2}  # restored once the last block left


def test_one_blas_thread_nests_and_restores_the_callers_count(
    two_blas_threads: None, blas_thread_counts: Callable[[], set[int]]
) -> None:
    with one_blas_thread():
        with one_blas_thread():
            assert blas_thread_counts() == {1}
        assert blas_thread_counts() == {1}  # the inner block's exit did not restore
    assert blas_thread_counts() == {2}
    with pytest.raises(RuntimeError), one_blas_thread():
        raise RuntimeError("a failing block restores too")
    assert blas_thread_counts() == {2}


def test_one_blas_thread_limits_scipys_blas_imported_after_its_first_use() -> None:
    # NumPy and SciPy each carry their own OpenBLAS; SciPy's often loads later.
    script = (
        "import susp_bo, numpy\n"
        "from susp_bo.numerics import one_blas_thread\n"
        "from threadpoolctl import threadpool_info, threadpool_limits\n"
        "with one_blas_thread(): pass\n"
        "import scipy.linalg\n"
        "threadpool_limits(limits=2, user_api='blas')\n"
        "with one_blas_thread():\n"
        "    inside = [p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']\n"
        "print(inside)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=120
    )
    inside = json.loads(done.stdout)
    if len(inside) < 2:
        pytest.skip("NumPy and SciPy share one BLAS library here")
    assert set(inside) == {1}  # NumPy's and SciPy's libraries, both on one thread
