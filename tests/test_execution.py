"""Tests of susp_bo.execution with real process pools and a real Dask LocalCluster."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from susp_bo.execution import (
    InProcessExecutor,
    RestartableProcessPool,
    TaskOutcome,
    make_executor,
    run_tasks,
)
from susp_bo.store import EvaluationStore


@pytest.fixture
def tasks_module(monkeypatch: pytest.MonkeyPatch) -> Iterator[ModuleType]:
    """tests/execution_tasks.py, importable by name here and in spawned workers."""
    monkeypatch.syspath_prepend(str(Path(__file__).parent))
    yield importlib.import_module("execution_tasks")


def _values(outcomes: list[TaskOutcome]) -> list[np.ndarray]:
    assert all(outcome.ok for outcome in outcomes), [o.reason for o in outcomes]
    return [outcome.value for outcome in outcomes]


def test_in_process_pool_and_dask_cluster_give_identical_results(
    tasks_module: ModuleType,
) -> None:
    distributed = pytest.importorskip("distributed")
    tasks = [(seed, 256) for seed in (7, 3, 11, 0, 5)]
    expected = [tasks_module.log_spectrum(*task) for task in tasks]

    with make_executor(workers=0) as executor:
        assert isinstance(executor, InProcessExecutor)
        in_process = _values(run_tasks(executor, tasks_module.log_spectrum, tasks, progress=False))
    with make_executor(workers=2) as executor:
        assert isinstance(executor, RestartableProcessPool)
        pool = _values(run_tasks(executor, tasks_module.log_spectrum, tasks, progress=False))
    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0"
        ) as cluster,
        make_executor(scheduler=cluster.scheduler_address) as executor,
    ):
        dask = _values(run_tasks(executor, tasks_module.log_spectrum, tasks, progress=False))
        raised = run_tasks(executor, tasks_module.misbehaving, [(4, "raise")], progress=False)
    assert (raised[0].ok, raised[0].failure_kind) == (False, "error")
    assert raised[0].reason.startswith("Diverged: simulation failed: carbody roll diverged")

    for name, results in (("in-process", in_process), ("process pool", pool), ("dask", dask)):
        assert len(results) == len(expected), name
        for got, want in zip(results, expected):
            assert got.dtype == np.float64
            np.testing.assert_array_equal(got, want, err_msg=name)  # bit-for-bit, in task order


def test_crashing_and_raising_tasks_become_failed_outcomes(tasks_module: ModuleType) -> None:
    modes = ["ok", "exit", "ok", "raise", "ok", "ok"]
    tasks = [(seed, mode) for seed, mode in enumerate(modes)]
    seen: list[int] = []
    with make_executor(workers=2) as executor:
        outcomes = run_tasks(
            executor,
            tasks_module.misbehaving,
            tasks,
            on_result=lambda outcome: seen.append(outcome.index),
            progress=False,
        )
        assert executor.restarts >= 1
        # the pool works after the crash
        again = run_tasks(executor, tasks_module.log_spectrum, [(1, 64)], progress=False)

    assert sorted(seen) == list(range(len(tasks)))  # on_result once per task
    assert [outcome.index for outcome in outcomes] == list(range(len(tasks)))
    crash, error = outcomes[1], outcomes[3]
    assert (crash.ok, crash.failure_kind, crash.value) == (False, "crash", None)
    assert "worker process died" in crash.reason
    assert (error.ok, error.failure_kind) == (False, "error")
    assert error.reason.startswith("Diverged: simulation failed: carbody roll diverged for seed 3")
    for index in (0, 2, 4, 5):
        assert outcomes[index].ok and outcomes[index].failure_kind is None
        np.testing.assert_array_equal(outcomes[index].value, tasks_module.log_spectrum(index, 64))
    np.testing.assert_array_equal(again[0].value, tasks_module.log_spectrum(1, 64))


def test_several_crashes_in_one_batch_are_each_pinned_on_their_task(
    tasks_module: ModuleType,
) -> None:
    modes = ["exit", "ok", "ok", "exit", "ok", "raise", "ok", "exit"]
    with make_executor(workers=2) as executor:
        outcomes = run_tasks(
            executor, tasks_module.misbehaving, list(enumerate(modes)), progress=False
        )
    kinds = [outcome.failure_kind for outcome in outcomes]
    assert kinds == [{"exit": "crash", "raise": "error", "ok": None}[mode] for mode in modes]
    for index in (1, 2, 4, 6):
        np.testing.assert_array_equal(outcomes[index].value, tasks_module.log_spectrum(index, 64))


def test_transient_crash_is_retried_and_innocent_tasks_are_rerun(
    tasks_module: ModuleType, tmp_path: Path
) -> None:
    tasks = [(seed, str(tmp_path)) for seed in range(4)]
    for seed in (0, 2, 3):  # only seed 1 crashes, once: it broke the pool with others in flight
        (tmp_path / f"crashed-{seed}").touch()
    with make_executor(workers=2) as executor:
        outcomes = run_tasks(executor, tasks_module.crash_once, tasks, progress=False)
        assert executor.restarts >= 1
    for seed, outcome in enumerate(outcomes):
        assert outcome.ok, outcome.reason
        np.testing.assert_array_equal(outcome.value, tasks_module.log_spectrum(seed, 64))


def test_plain_process_pool_crash_fails_the_affected_tasks_without_raising(
    tasks_module: ModuleType,
) -> None:
    import multiprocessing

    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as executor:
        outcomes = run_tasks(
            executor, tasks_module.misbehaving, [(0, "ok"), (1, "exit")], progress=False
        )
        assert outcomes[0].ok
        assert (outcomes[1].ok, outcomes[1].failure_kind) == (False, "crash")
        later = run_tasks(executor, tasks_module.misbehaving, [(2, "ok")], progress=False)
    assert (later[0].ok, later[0].failure_kind) == (False, "crash")  # broken pool: no new work


def test_in_process_raising_task_is_recorded_in_the_store_as_it_completes(
    tasks_module: ModuleType, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tasks = [(0, "ok"), (1, "raise"), (2, "ok")]
    with EvaluationStore(tmp_path / "store.sqlite", {"rig": "test"}) as store:
        counts: list[int] = []

        def record(outcome: TaskOutcome) -> None:
            seed, _mode = tasks[outcome.index]
            parameters = np.array([float(seed)])
            if outcome.ok:
                store.record_ok(parameters, "track-0", outcome.value[None, :], outcome.seconds)
            else:
                store.record_failure(parameters, "track-0", outcome.reason, outcome.seconds)
            counts.append(store.count())

        with make_executor(workers=0) as executor:
            outcomes = run_tasks(executor, tasks_module.misbehaving, tasks, on_result=record)
        assert counts == [1, 2, 3]  # recorded one by one, not at the end of the batch
        # progress on stderr: plain lines here (stderr is not a terminal under pytest)
        assert "simulations: 3/3 run (100 %)" in capsys.readouterr().err
        assert [o.ok for o in outcomes] == [True, False, True]
        assert store.count("failed") == 1
        failed = store.lookup(np.array([1.0]), "track-0")
        assert failed is not None and failed.failure_kind == "error"
        assert "carbody roll diverged for seed 1" in failed.failure_reason
        ok = store.lookup(np.array([2.0]), "track-0")
        assert ok is not None
        np.testing.assert_array_equal(ok.spectra[0], tasks_module.log_spectrum(2, 64))


def test_make_executor_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="give one of them"), make_executor(2, "tcp://x:1"):
        pass
    with pytest.raises(ValueError, match="workers: -1 is not allowed"), make_executor(-1):
        pass


@pytest.mark.parametrize(
    ("address", "problem"),
    [
        ("tcp://10.0.0.5:8786", None),
        ("10.0.0.5:8786", None),  # Dask's default protocol is tcp
        ("tls://[::1]:8786", None),
        ("inproc://10.0.0.5/1234/1", None),
        ("notanaddress", "no port number"),
        ("tcp://host", "no port number"),
        ("tcp://host:0", "no port number"),
        ("host:99999", "no port number"),
        ("tcp://:8786", "no host"),
        ("foo://h:1", "unknown protocol 'foo'"),
        ("inproc://", "no location"),
        # session 29's probe: an unclosed bracket passed, and Dask timed out after 20 s
        ("tcp://[::1", "'[' before the host is not closed"),
        ("tcp://[::1]8786", "after ']' comes ':port'"),
        ("tcp://::1:8786", "an IPv6 host goes in brackets"),
        ("tcp://[]:8786", "no host"),
        ("tcp://[::1]", "no port number"),
    ],
)
def test_scheduler_address_grammar(address: str, problem: str | None) -> None:
    from susp_bo.execution import scheduler_address_problem

    found = scheduler_address_problem(address)
    assert (found is None) if problem is None else (found is not None and problem in found)


def test_a_malformed_scheduler_is_refused_before_connecting() -> None:
    # Dask raised a bare ValueError from inside Client (and its half-made client then timed
    # out again when collected): now refused before any connection, naming the address
    with (
        pytest.raises(ValueError, match=r"scheduler 'notanaddress': no port number"),
        make_executor(scheduler="notanaddress", connect_timeout_s=1.0),
    ):
        pass


def test_unreachable_scheduler_is_a_clear_connection_error() -> None:
    pytest.importorskip("distributed")
    with (
        pytest.raises(ConnectionError, match=r"scheduler 'tcp://127\.0\.0\.1:9': cannot connect"),
        make_executor(scheduler="tcp://127.0.0.1:9", connect_timeout_s=1.0),
    ):
        pass


def test_default_workers_is_the_cpu_affinity() -> None:
    from susp_bo.execution import default_workers

    expected = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    assert default_workers() == (expected or os.cpu_count())


def test_a_worker_of_a_program_that_loaded_numpy_first_still_runs_blas_on_one_thread() -> None:
    """Spawned workers import the program's main module before the pool's initializer runs:
    when that module imports NumPy, its BLAS has read the thread variables already; the
    initializer limits it anyway (N workers on N cores, and the same bits as the CLI)."""
    code = (
        "import numpy, threadpoolctl\n"
        "from susp_bo.execution import _single_threaded_worker\n"
        "_single_threaded_worker()\n"
        "print(max(i['num_threads'] for i in threadpoolctl.threadpool_info()"
        " if i['user_api'] == 'blas'))\n"
    )
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env["OPENBLAS_NUM_THREADS"] = "2"
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert done.stdout.strip() == "1", done.stdout + done.stderr
