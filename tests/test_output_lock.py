"""One writer per results folder: the lock, in this process and against another one."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from susp_bo.output_lock import LOCK_NAME, OutputFolderBusy, hold_output_folder, refuse_if_busy


def test_this_process_may_hold_a_folder_again_and_lets_go_at_the_outer_end(
    tmp_path: Path,
) -> None:
    refuse_if_busy(tmp_path)  # no lock file yet: nothing to say
    with hold_output_folder(tmp_path):
        assert (tmp_path / LOCK_NAME).read_text().startswith("process ")
        refuse_if_busy(tmp_path)  # held by this process: not busy for it
        with hold_output_folder(tmp_path):  # demo holds it, its study takes it again
            pass
        assert _busy_for_another_process(tmp_path)  # still held after the inner block
    assert not _busy_for_another_process(tmp_path)  # released at the outer end


def _busy_for_another_process(folder: Path) -> bool:
    check = (
        "import sys; from pathlib import Path; from susp_bo.output_lock import refuse_if_busy\n"
        "try:\n    refuse_if_busy(Path(sys.argv[1]))\nexcept ValueError:\n    sys.exit(3)\n"
    )
    return subprocess.run([sys.executable, "-c", check, str(folder)]).returncode == 3


def test_another_process_holding_the_folder_is_named_and_its_death_frees_it(
    tmp_path: Path, held_elsewhere
) -> None:
    with held_elsewhere(tmp_path) as pid:
        with pytest.raises(OutputFolderBusy, match=rf"in use by process {pid} "):
            refuse_if_busy(tmp_path)
        with (  # retried for ~0.1 s, then refused
            pytest.raises(OutputFolderBusy, match="then run yours again"),
            hold_output_folder(tmp_path),
        ):
            pass
    refuse_if_busy(tmp_path)  # the holder was killed: free again
    with hold_output_folder(tmp_path):
        pass
