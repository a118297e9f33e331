"""``susp-bo simulate``: one run, its files, and bad input refused before any simulation."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from susp_bo.cli import main


def test_simulate_writes_signals_spectra_and_a_figure(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    params = tmp_path / "params.toml"
    params.write_text("secondary_vertical_damping = 30000.0\n")
    out = tmp_path / "out"
    code = main(
        [
            "simulate",
            "hst_trailer",
            "--out",
            str(out),
            "--params",
            str(params),
            "--duration",
            "8",
            "--speed",
            "70",
            "--seed",
            "3",
        ]
    )
    assert code == 0, capsys.readouterr().err
    with np.load(out / "signals.npz") as signals:  # closed here: an open npz warns when collected
        accelerations = signals["accelerations_m_s2"]
    spectra = json.loads((out / "spectra.json").read_text())
    assert accelerations.shape[0] == len(spectra["channels"])
    assert spectra["parameters"]["secondary_vertical_damping"] == 30000.0
    assert spectra["speed_m_s"] == 70.0
    values = np.array(spectra["log_amplitude"])
    assert values.shape == (len(spectra["channels"]), len(spectra["frequencies_hz"]))
    assert np.all(np.isfinite(values))
    assert (out / "simulate.png").stat().st_size > 10_000
    # a second run into the same folder is refused, the first run's files kept as they were
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    assert main(["simulate", "hst_trailer", "--out", str(out), "--seed", "4"]) == 2
    assert "already holds a simulate run (signals.npz, spectra.json" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--params", "{params}"], "unknown parameter 'no_such_parameter'"),
        (["--speed", "-3"], "argument --speed: '-3' is not allowed"),
        (["--duration", "nan"], "argument --duration: 'nan' is not allowed"),
    ],
)
def test_bad_input_is_refused_with_the_field_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], arguments: list[str], message: str
) -> None:
    params = tmp_path / "params.toml"
    params.write_text("no_such_parameter = 1.0\n")
    arguments = [a.replace("{params}", str(params)) for a in arguments]
    code = main(["simulate", "hst_trailer", "--out", str(tmp_path / "out"), *arguments])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out" / "signals.npz").exists()


def test_unknown_rig_lists_the_shipped_ones(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["simulate", "no_such_rig", "--out", str(tmp_path)]) == 2
    assert "hst_trailer" in capsys.readouterr().err
