"""The command line: help lists every DESIGN.md command, unbuilt commands fail loudly."""

from __future__ import annotations

import subprocess
import sys

import pytest

from susp_bo import __version__
from susp_bo.cli import build_parser, main

COMMANDS = ("demo", "simulate", "synth", "calibrate", "diagnose", "import", "monitor")


def test_help_lists_every_command() -> None:
    text = build_parser().format_help()
    for command in COMMANDS:
        assert command in text


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert "usage: susp-bo " + command in capsys.readouterr().out


def test_no_command_prints_help_and_fails(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().err


def test_python_dash_m_runs_the_same_cli() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "susp_bo", "--version"], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0
    assert __version__ in done.stdout


@pytest.mark.parametrize(
    "command, expected",
    [
        (["calibrate", "{missing}/study.toml"], ["RIG_OR_STUDY", "does not exist"]),
        (["diagnose", "{missing}", "--out", "{tmp}/d"], ["RESULT_DIR", "no finished calibration"]),
        (["monitor", "{missing}", "--out", "{tmp}/m"], ["not a folder", "monitoring folder"]),
        (["monitor", "{tmp}", "--out", "{tmp}/file/sub"], ["--out", "existing file"]),
    ],
)
def test_bad_arguments_are_refused_without_loading_torch(
    tmp_path, command: list[str], expected: list[str]
) -> None:
    """Refusing a missing study, results folder or monitoring folder, or an --out that cannot
    be a folder, must not first import torch and the GP stack (≈ 4 s): the commands check
    their paths before the heavy imports, and the exit-2 path looks up only the error types of
    modules already loaded."""
    (tmp_path / "file").write_text("not a folder")
    argv = [a.format(missing=tmp_path / "missing", tmp=tmp_path) for a in command]
    code = (
        "import sys\n"
        "from susp_bo.cli import main\n"
        f"rc = main({argv!r})\n"
        "print(rc, 'torch' in sys.modules)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=False, timeout=120
    )
    assert done.stdout.split() == ["2", "False"], done.stderr[-2000:]
    assert all(text in done.stderr for text in expected), done.stderr
    assert "Traceback" not in done.stderr


def test_an_uninformative_design_is_a_user_error_not_a_traceback() -> None:
    """A log L that is constant over the design (parameters that do not reach the
    channels) stops the study with one message and exit code 2."""
    from susp_bo.calibration.loop import UninformativeDesignError
    from susp_bo.cli import _user_error_types

    assert issubclass(UninformativeDesignError, _user_error_types())


def test_ctrl_c_says_what_was_kept_and_how_to_continue(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Ctrl-C printed only "interrupted": the user was not told the store is kept, nor to
    resume (outside probe, session 23)."""
    import susp_bo.commands.calibrate as calibrate_command

    def interrupted(args: object) -> int:
        raise KeyboardInterrupt

    monkeypatch.setattr(calibrate_command, "run_calibrate", interrupted)
    assert main(["calibrate", "study.toml"]) == 130
    err = capsys.readouterr().err
    assert err.startswith("susp-bo calibrate: interrupted; the likelihood evaluations")
    assert "with --resume to continue" in err and "Traceback" not in err


def test_sigterm_is_reported_like_ctrl_c_and_the_handler_restored(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """SIGTERM (``kill PID``, a batch scheduler's stop) ended a run in silence, without the
    clean-up of Ctrl-C (outside probe, session 23): it now raises in the main thread, the
    user is told what was kept, the exit code is 143, and the caller's handler is back."""
    import os
    import signal
    import time

    import susp_bo.commands.calibrate as calibrate_command

    cleaned = []

    def terminated(args: object) -> int:
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)  # the signal arrives first
            return 0
        finally:
            cleaned.append(True)  # a finally block of the running command runs

    monkeypatch.setattr(calibrate_command, "run_calibrate", terminated)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["calibrate", "study.toml"]) == 143
    err = capsys.readouterr().err
    assert err.startswith("susp-bo calibrate: terminated (SIGTERM); the likelihood evaluations")
    assert "with --resume to continue" in err and "Traceback" not in err
    assert cleaned == [True]
    assert signal.getsignal(signal.SIGTERM) is before


def test_a_full_disk_is_a_message_not_a_traceback(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A disk that filled up while a result was written ended in a traceback (session 23's
    note): it is now one line saying what was kept and to rerun with --resume, exit 1."""
    import errno

    import susp_bo.commands.calibrate as calibrate_command

    def disk_full(args: object) -> int:
        raise OSError(errno.ENOSPC, "No space left on device", "out/result.json")

    monkeypatch.setattr(calibrate_command, "run_calibrate", disk_full)
    assert main(["calibrate", "study.toml"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(
        "susp-bo calibrate: cannot write (out/result.json): No space left on device; the "
        "likelihood evaluations already stored are kept"
    )
    assert "rerun the same command with --resume" in err and "Traceback" not in err

    def other(args: object) -> int:
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(calibrate_command, "run_calibrate", other)
    with pytest.raises(OSError, match="Input/output error"):  # not hidden: a real fault
        main(["calibrate", "study.toml"])


def test_a_full_disk_under_the_evaluation_store_is_a_message_too(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The store is SQLite, whose full disk is an OperationalError, not an OSError (review,
    session 24): the same one line, exit 1."""
    import sqlite3

    import susp_bo.commands.calibrate as calibrate_command

    def disk_full(args: object) -> int:
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(calibrate_command, "run_calibrate", disk_full)
    assert main(["calibrate", "study.toml"]) == 1
    err = capsys.readouterr().err
    assert err.startswith(
        "susp-bo calibrate: cannot write (the evaluation store): database or disk is full; "
    )

    def locked(args: object) -> int:
        raise sqlite3.OperationalError("database is locked")

    monkeypatch.setattr(calibrate_command, "run_calibrate", locked)
    with pytest.raises(sqlite3.OperationalError):  # not a disk failure: not hidden
        main(["calibrate", "study.toml"])
