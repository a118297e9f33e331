"""``susp-bo simulate``: one run, its files, and bad input refused before any simulation."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from susp_bo.cli import main
from susp_bo.rig.catalog import rig_path


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


def test_a_run_that_diverges_is_refused_naming_the_file_and_values_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # a conicity of 0.9 makes the wheelsets hunt: the run diverges after about 1.4 s
    params = tmp_path / "hunting.toml"
    params.write_text("contact_equivalent_conicity = 0.9\n")
    out = tmp_path / "s"
    argv = ["simulate", "hst_trailer", "--out", str(out), "--params", str(params)]
    code = main([*argv, "--duration", "8"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    assert (
        f"--params {params}: the simulation of rig 'hst_trailer' with "
        "contact_equivalent_conicity = 0.9, at 83.33 m/s with a time step of 0.002 s, failed: "
        "diverged at t = 1." in err
    )
    assert "nothing was written" in err and "admissible bounds" in err and "time_step_s" in err
    assert not out.exists()


@pytest.mark.parametrize("speed", ["20", "1e-9"])
def test_a_speed_below_the_time_steps_minimum_is_refused_naming_it(
    fast_rig: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], speed: str
) -> None:
    # the fast rig's 5 ms step cannot simulate the creep damping below 24.99 m/s: every
    # such run diverged within 0.2 s (with a traceback)
    out = tmp_path / "s"
    code = main(["simulate", str(fast_rig), "--out", str(out), "--speed", speed])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"--speed: {float(speed):g} m/s is not allowed: below the minimum speed 24.99 m/s" in err
    assert "Traceback" not in err and not out.exists()


@pytest.mark.parametrize(
    ("edit", "needle"),
    [
        ({"sensors": "roof"}, "[[sensors]] entry 1 ('carbody_front_vertical'): body 'roof' is not"),
        ({"effects": {"nosuch": {}}}, "[effects.nosuch]: unknown effect 'nosuch'; allowed effects"),
    ],
    ids=["sensor-body", "effect"],
)
def test_a_rig_entry_that_cannot_be_built_is_refused_at_load(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], edit: dict, needle: str
) -> None:
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    if "sensors" in edit:
        document["sensors"][0]["body"] = edit["sensors"]
    else:
        document["effects"] = edit["effects"]
    rig = tmp_path / "edited.toml"
    rig.write_text(tomli_w.dumps(document))
    out = tmp_path / "s"
    assert main(["simulate", str(rig), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"susp-bo simulate: {rig}: {needle}" in err
    assert "Traceback" not in err and not out.exists()
