"""End to end on PyBullet-generated data: a hidden carbody bending mode is found and named.

The measured runs come from the PyBullet world (time integration of the
multibody with the effect on; elements at their slopes, the time-domain
counterpart of the fast path); the workflow fits, checks and ranks on the
linearised rig.
"""

from __future__ import annotations

from susp_bo.discrepancy.scenarios import synthesize_problem
from susp_bo.discrepancy.workflow import run_workflow


def test_pybullet_data_with_hidden_bending_name_it(base_spec, linear_simulator) -> None:
    problem = synthesize_problem(
        base_spec,
        ("carbody_bending", {"frequency_hz": 9.0}),
        nu=3,
        seed=21,
        noise_m_s2=0.02,
        generator="pybullet_linear",
    )
    report = run_workflow(problem, linear_simulator)
    bands = report.before.bands
    assert any(
        b.channel == "carbody_mid_vertical" and b.f_low_hz < 9.0 < b.f_high_hz for b in bands
    )
    assert report.named_effect == "carbody_bending"
    assert report.gap_after["value"] <= 0.5 * report.gap_before["value"]
    frequency = report.augmented.parameters()["carbody_bending_frequency_hz"]
    assert abs(frequency - 9.0) < 0.3
