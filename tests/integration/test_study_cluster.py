"""A real Dask LocalCluster runs a small study and gives the process pool's result."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from susp_bo.calibration.study import run_study
from susp_bo.json_files import json_ready
from susp_bo.study_config import ExecutorConfig, load_study_config

pytestmark = pytest.mark.slow


def test_local_cluster_study_equals_process_pool_study(
    fast_rig, fast_data, study_writer, tmp_path: Path
) -> None:
    distributed = pytest.importorskip("distributed")
    pool_config = load_study_config(
        study_writer(tmp_path, fast_rig, fast_data, tmp_path / "pool", "workers = 2")
    )
    pool_payload, pool_result = run_study(pool_config, progress=False)
    # the Python API's dict of a result is result.json's calibration part, key for key
    written = json.loads((tmp_path / "pool" / "result.json").read_text())
    calibration = json.loads(json.dumps(json_ready(pool_result.to_dict())))  # NaN as null
    assert calibration == {key: written[key] for key in calibration}
    assert {"bounds", "posterior_sd", "n_failed_evaluations", "local_search"} <= set(calibration)

    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        cluster_config = dataclasses.replace(
            pool_config,
            out=tmp_path / "cluster",
            executor=ExecutorConfig(scheduler=cluster.scheduler_address),
        )
        cluster_payload, _ = run_study(cluster_config, progress=False)

    for payload in (pool_payload, cluster_payload):
        payload.pop("wall_time_s")
    assert cluster_payload == pool_payload
    assert json.loads((tmp_path / "cluster" / "result.json").read_text())["n_simulations"] == 20
