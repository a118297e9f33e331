"""One writer per results folder: the lock, in this process and against another one."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from susp_bo.output_lock import LOCK_NAME, OutputFolderBusy, hold_output_folder, refuse_if_busy

HOLD = (
    "import sys, time; from pathlib import Path; "
    "from susp_bo.output_lock import hold_output_folder\n"
    "with hold_output_folder(Path(sys.argv[1])):\n"
    "    print('held', flush=True); time.sleep(60)\n"
)


def test_a_second_holder_is_refused_until_the_first_lets_go(tmp_path: Path) -> None:
    refuse_if_busy(tmp_path)  # no lock file yet: nothing to say
    with hold_output_folder(tmp_path):
        assert (tmp_path / LOCK_NAME).read_text().startswith("process ")
        with pytest.raises(OutputFolderBusy, match=r"is in use by process \d+"):
            refuse_if_busy(tmp_path)
        with (
            pytest.raises(OutputFolderBusy, match="choose another output folder"),
            hold_output_folder(tmp_path),
        ):
            pass
    refuse_if_busy(tmp_path)  # released: free again
    with hold_output_folder(tmp_path):
        pass


def test_another_process_holding_the_folder_is_named_and_its_death_frees_it(
    tmp_path: Path,
) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLD, str(tmp_path)], stdout=subprocess.PIPE, text=True
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputFolderBusy, match=rf"in use by process {holder.pid} "):
            refuse_if_busy(tmp_path)
    finally:
        holder.kill()  # kill -9: the operating system releases the lock
        holder.communicate()  # waits, and closes the pipe
    refuse_if_busy(tmp_path)
    with hold_output_folder(tmp_path):
        pass
