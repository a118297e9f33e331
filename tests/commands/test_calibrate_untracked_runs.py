"""``susp-bo calibrate`` on runs whose track was not measured, with the default output-error
model: exit code 2 and one message naming the file and the way out, before any simulation."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

from susp_bo.data.run_files import save_run
from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.spec import load_rig_spec


def test_calibrate_refuses_runs_without_geometry_under_the_default_model(
    fast_rig: Path, tmp_path: Path
) -> None:
    data = tmp_path / "data"
    for index, run in enumerate(synthesize_runs(load_rig_spec(fast_rig), nu=2, seed=7)):
        save_run(dataclasses.replace(run, geometry=None), data / f"run_{index:03d}.h5")
    study = tmp_path / "study.toml"
    study.write_text(
        f'rig = "{fast_rig}"\ndata = "{data}"\nout = "{tmp_path / "out"}"\n'
        'parameters = ["secondary_vertical_damping", "yaw_damper_damping"]\n'
        "[budget]\nmax_evaluations = 10\ninitial_design = 6\nallow_small = true\n"
    )
    done = subprocess.run(
        [sys.executable, "-m", "susp_bo", "calibrate", str(study)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert done.returncode == 2, done.stderr[-3000:]
    assert "Traceback" not in done.stderr
    assert (
        f"susp-bo calibrate: data: {data / 'run_000.h5'}: the run has no track geometry"
    ) in done.stderr
    assert "output_error.model = 'unpaired' simulates every run on its own measured track" in (
        done.stderr
    )
    assert '[output_error] model = "track_statistics"' in done.stderr
    assert not (tmp_path / "out" / "evaluations.sqlite").exists()  # nothing simulated
