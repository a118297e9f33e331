"""Progress and logs: plain periodic lines when stderr is not a terminal, no escape codes,
no PyBullet banners."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest

from susp_bo.execution import make_executor, run_tasks
from susp_bo.progress import LineProgress, progress_bar

TESTS = Path(__file__).parent


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_stream_that_is_not_a_terminal_gets_plain_lines(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("SUSP_BO_PROGRESS", raising=False)
    stream = io.StringIO()
    with progress_bar(total=4, desc="simulations", unit="run", file=stream) as bar:
        assert isinstance(bar, LineProgress)
        for _ in range(4):
            bar.update(1)
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("simulations: 0/4 run (0 %)")
    assert lines[-1].startswith("simulations: 4/4 run (100 %)")
    assert "\r" not in stream.getvalue() and "\x1b" not in stream.getvalue()


def test_a_terminal_gets_a_tqdm_bar(monkeypatch: pytest.MonkeyPatch) -> None:
    from tqdm import tqdm

    monkeypatch.delenv("SUSP_BO_PROGRESS", raising=False)
    with progress_bar(total=2, desc="x", file=_Terminal()) as bar:
        assert isinstance(bar, tqdm)
    monkeypatch.setenv("SUSP_BO_PROGRESS", "lines")
    assert isinstance(progress_bar(total=2, file=_Terminal(), disable=True), LineProgress)


def test_lines_are_periodic_not_per_update() -> None:
    stream = io.StringIO()
    bar = LineProgress(total=1000, desc="steps", file=stream, interval_s=3600.0)
    for _ in range(1000):
        bar.update(1)
    bar.close()
    bar.close()  # idempotent
    assert len(stream.getvalue().splitlines()) == 2  # start and end only
    quiet = io.StringIO()
    with LineProgress(total=3, file=quiet, disable=True) as bar:
        bar.update(3)
    assert quiet.getvalue() == ""


def test_the_final_line_is_not_printed_twice() -> None:
    """A periodic line printed at the last update was followed by the same line from
    ``close`` (a resumed calibration's log ended with "log L evaluations: 51/60" twice)."""
    stream = io.StringIO()
    bar = LineProgress(total=3, desc="steps", file=stream, interval_s=0.0)
    bar.update(3)  # the interval has passed: printed now
    bar.close()
    lines = stream.getvalue().splitlines()
    assert [line.split(",")[0] for line in lines] == [
        "steps: 0/3 it (0 %)",
        "steps: 3/3 it (100 %)",
    ]


def test_run_tasks_reports_plain_lines_on_a_non_terminal(
    capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv("SUSP_BO_PROGRESS", raising=False)
    monkeypatch.syspath_prepend(str(TESTS))
    import execution_tasks

    with make_executor(workers=0) as executor:
        run_tasks(executor, execution_tasks.log_spectrum, [(1, 64), (2, 64)], desc="sims")
    err = capfd.readouterr().err
    assert "sims: 2/2 run (100 %)" in err
    assert "\x1b" not in err and "\r" not in err


def test_pybullet_prints_no_banner_on_import_or_connect() -> None:
    """PyBullet writes 'pybullet build time' (import) and 'argv[0]=' (connect) from C."""
    code = (
        "from susp_bo.rig.world import VehicleWorld\n"
        "world = VehicleWorld(0.002)\n"
        "world.close()\n"
        "print('done')\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    assert done.stdout == "done\n"
    assert "argv[0]" not in done.stderr and "pybullet build time" not in done.stderr
