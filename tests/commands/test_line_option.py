"""``--line FILE`` of ``susp-bo simulate`` and ``susp-bo synth``: curves in, bad lines refused."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from susp_bo.cli import main
from susp_bo.data.measured import load_runs
from susp_bo.data.run_validation import validate_run

LINE = """
[line]
name = "test curve"

[[segments]]
type = "tangent"
length_m = 50.0

[[segments]]
type = "transition"
length_m = 150.0

[[segments]]
type = "curve"
length_m = {curve}
radius_m = {radius}
cant_mm = {cant}
direction = "left"
"""


def _line(tmp_path: Path, radius: float = 7000.0, cant: float = 0.0, curve: float = 4000.0) -> Path:
    path = tmp_path / "line.toml"
    path.write_text(LINE.format(radius=radius, cant=cant, curve=curve))
    return path


def test_simulate_follows_the_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    line = _line(tmp_path)
    arguments = ["simulate", "hst_trailer", "--out", str(out), "--duration", "8", "--speed", "70"]
    assert main([*arguments, "--line", str(line)]) == 0, capsys.readouterr().err
    with np.load(out / "signals.npz") as signals:  # closed here: an open npz warns when collected
        channels = list(signals["channels"])
        lateral = signals["accelerations_m_s2"][channels.index("carbody_mid_lateral")]
    centripetal = 70.0**2 / 7000.0  # no cant: V²/R, plus the carbody's roll-out (≈ 11 %)
    assert np.mean(lateral[-200:]) == pytest.approx(1.11 * centripetal, rel=0.05)
    assert json.loads((out / "spectra.json").read_text())["line"] == str(line)


def test_synth_writes_the_design_into_the_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "data"
    line = _line(tmp_path, cant=150.0)
    code = main(["synth", "hst_trailer", "--out", str(out), "--nu", "1", "--line", str(line)])
    assert code == 0, capsys.readouterr().err
    (run,) = load_runs(out)
    assert run.design is not None
    assert run.design.curvature(1000.0) == pytest.approx(1.0 / 7000.0)
    validate_run(run)


@pytest.mark.parametrize("command", ["simulate", "synth"])
@pytest.mark.parametrize(
    ("line", "message"),
    [
        ({"radius": 120.0}, "radius_m: got 120 m; below the minimum 150 m"),
        ({"cant": 250.0}, "cant_mm: got 250 mm; above the allowed maximum 180 mm"),
        ({"cant": 0.15}, "suggests metres given as millimetres"),
        ({"curve": 100.0}, "covers 0 … 300 m but the run"),
        # was a numpy overflow warning and exit 0
        ({"curve": 1e300}, "segment 3.length_m: got 1e+300 m; above the maximum 2e+07 m"),
    ],
)
def test_bad_lines_are_refused_before_simulating(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    command: str,
    line: dict[str, float],
    message: str,
) -> None:
    path = _line(tmp_path, **line)
    out = tmp_path / "out"
    assert main([command, "hst_trailer", "--out", str(out), "--line", str(path)]) == 2
    error = capsys.readouterr().err
    assert message in error and str(path) in error
    assert "Traceback" not in error and "RuntimeWarning" not in error
    assert not out.exists()
