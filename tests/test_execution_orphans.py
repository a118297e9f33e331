"""Workers die with their parent: after ``kill -9`` of a process running a pool, no child
(pool worker, multiprocessing resource tracker) stays alive."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")

TESTS = Path(__file__).parent
PARENT = """
import sys, time
sys.path.insert(0, {tests!r})
from susp_bo.execution import make_executor
import execution_tasks
with make_executor(workers=2) as pool:
    futures = [pool.submit(execution_tasks.sleep_then_return, 600.0) for _ in range(3)]
    print("running", flush=True)
    time.sleep(600)
"""


def _status(pid: int) -> tuple[int, str] | None:
    """(parent pid, state) from /proc/<pid>/stat, None when the process is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return None
    fields = text[text.rindex(")") + 2 :].split()
    return int(fields[1]), fields[0]


def _alive(pid: int) -> bool:
    status = _status(pid)
    return status is not None and status[1] != "Z"  # a zombie has exited


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            status = _status(int(entry.name))
            if status is not None and status[0] == pid:
                found.append(int(entry.name))
    return found


def test_kill_9_of_the_parent_leaves_no_worker_or_resource_tracker() -> None:
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT.format(tests=str(TESTS))],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,  # the resource tracker reports the semaphores it frees
        text=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    children: list[int] = []
    try:
        assert parent.stdout is not None
        assert parent.stdout.readline().strip() == "running"
        for _ in range(600):  # the pool spawns its workers while the tasks are submitted
            children = _children(parent.pid)
            if len(children) >= 3:  # 2 workers + the resource tracker
                break
            time.sleep(0.1)
        assert len(children) >= 3, children
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=60)
        # liveness bound, not a speed figure: the watchdog polls every 0.5 s
        deadline = time.monotonic() + 60.0
        while any(_alive(pid) for pid in children) and time.monotonic() < deadline:
            time.sleep(0.2)
        survivors = [pid for pid in children if _alive(pid)]
        assert survivors == [], f"still alive after the parent's SIGKILL: {survivors}"
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        if parent.stdout is not None:
            parent.stdout.close()
        for pid in children:  # recorded before the kill (re-parented since)
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
