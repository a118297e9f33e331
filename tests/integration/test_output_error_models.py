"""The study's output-error model: unpaired by default, paired on request, both recorded."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from susp_bo.calibration.likelihood import OutputError, estimate_output_error
from susp_bo.calibration.paired_error import PairedOutputError
from susp_bo.calibration.study import output_error_payload
from susp_bo.calibration.study_preparation import STORE_NAME, prepare_study, store_fingerprint
from susp_bo.store import EvaluationStore, StoreMismatchError
from susp_bo.study_config import OutputErrorConfig, StudyConfig
from tests.integration.conftest import FAST_PARAMETERS


def _config(rig: Path, data: Path, out: Path, **error: object) -> StudyConfig:
    """A study of the fast rig; the paired model unless ``model`` says otherwise."""
    error.setdefault("model", "paired")
    return StudyConfig(
        rig=str(rig),
        data=data,
        out=out,
        parameters=FAST_PARAMETERS,
        output_error=OutputErrorConfig(**error),
    )


def test_unpaired_is_the_default_and_keeps_the_replicate_sigma(
    fast_rig: Path, fast_data: Path, tmp_path: Path
) -> None:
    default = StudyConfig(rig=str(fast_rig), data=fast_data, out=tmp_path / "c")
    assert default.output_error.model == "unpaired"
    assert isinstance(prepare_study(default).error, OutputError)
    paired = prepare_study(_config(fast_rig, fast_data, tmp_path / "a"))
    assert isinstance(paired.error, PairedOutputError)
    assert paired.error.noise_m_s2 == 0.005  # from the runs' metadata
    assert paired.error.n_samples == tuple(r.accelerations_m_s2.shape[1] for r in paired.runs)
    assert paired.error.model_error_sigma is None
    unpaired = prepare_study(_config(fast_rig, fast_data, tmp_path / "b", model="unpaired"))
    assert isinstance(unpaired.error, OutputError)
    assert unpaired.error == estimate_output_error(unpaired.measured)  # as before issue 10
    assert output_error_payload(paired)["model"] == "paired"
    assert output_error_payload(paired)["model_error"] == "profiled"
    assert output_error_payload(unpaired)["model"] == "unpaired"
    fixed = prepare_study(_config(fast_rig, fast_data, tmp_path / "c", sigma=0.05))
    assert fixed.error.model_error_sigma == (0.05,) * len(fixed.spec.channels)


def test_a_store_of_the_other_model_is_refused(
    fast_rig: Path, fast_data: Path, tmp_path: Path
) -> None:
    out = tmp_path / "study"
    out.mkdir()
    unpaired = prepare_study(_config(fast_rig, fast_data, out, model="unpaired"))
    with EvaluationStore(out / STORE_NAME, store_fingerprint(unpaired)):
        pass
    paired = prepare_study(_config(fast_rig, fast_data, out), resume=True)
    with pytest.raises(StoreMismatchError, match="output_error"):
        EvaluationStore(out / STORE_NAME, store_fingerprint(paired))


def test_paired_log_l_is_highest_near_the_truth_on_pybullet_data(
    fast_rig: Path, fast_data: Path, tmp_path: Path
) -> None:
    """PyBullet data, PyBullet model on the same tracks: the truth beats a 10 % change."""
    from concurrent.futures import ThreadPoolExecutor

    from susp_bo.calibration.study import study_evaluator
    from tests.integration.conftest import FAST_TRUTH

    study = prepare_study(_config(fast_rig, fast_data, tmp_path / "d"))
    truth = np.array([FAST_TRUTH[n] for n in FAST_PARAMETERS])
    W = np.stack([truth, truth * np.array([1.1, 1.0]), truth * np.array([1.0, 0.9])])
    with (
        EvaluationStore(tmp_path / "d.sqlite", store_fingerprint(study)) as store,
        ThreadPoolExecutor(1) as pool,
    ):
        values = study_evaluator(study, store, pool, progress=False)(W)
    assert np.all(np.isfinite(values))
    assert values[0] > values[1] + 10 and values[0] > values[2] + 10
