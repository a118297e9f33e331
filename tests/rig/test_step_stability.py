"""The slowest speed a time step can simulate: the explicit step's limit, checked against
real runs of the reference rig."""

from __future__ import annotations

import math

import numpy as np
import pytest

from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.simulator import Rig, synthetic_track
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.step_stability import minimum_speed_m_s, speed_problem, step_is_stable


@pytest.mark.parametrize(
    ("time_step_s", "minimum_m_s"),
    # measured with PyBullet: 3.8 / 3.9, 7.8 / 8.0 and 24.5 / 25.0 m/s diverge / run
    [(0.001, 3.87), (0.002, 7.91), (0.005, 24.99)],
)
def test_the_minimum_speed_matches_where_runs_start_to_diverge(
    reference_spec: RigSpec, time_step_s: float, minimum_m_s: float
) -> None:
    assembly = build_assembly(reference_spec)
    assert minimum_speed_m_s(assembly, time_step_s) == pytest.approx(minimum_m_s, abs=1e-9)
    assert not step_is_stable(assembly, minimum_m_s - 0.01, time_step_s)
    assert step_is_stable(assembly, minimum_m_s, time_step_s)


def test_a_run_at_the_minimum_speed_runs_and_stays_physical(reference_spec: RigSpec) -> None:
    spec = reference_spec.with_simulation(
        time_step_s=0.005, speed_m_s=25.0, duration_s=8.0, warm_up_s=1.0
    )
    assert speed_problem(spec, 25.0) is None
    with Rig(spec) as rig:
        response = rig.simulate(synthetic_track(spec, seed=1))
    assert np.max(np.abs(response.accelerations_m_s2)) < 10.0  # m/s², a ride response


def test_no_speed_is_stable_with_a_step_too_long(reference_spec: RigSpec) -> None:
    assert math.isinf(minimum_speed_m_s(build_assembly(reference_spec), 0.01))
    problem = speed_problem(reference_spec.with_simulation(time_step_s=0.01), 83.33)
    assert problem is not None and problem.startswith("[simulation] time_step_s: 0.01 s is")


def test_hunting_is_not_mistaken_for_an_unstable_step(reference_spec: RigSpec) -> None:
    # a conicity of 0.9 makes the car hunt at 83 m/s (it diverges in PyBullet at ~1.4 s):
    # physics, which the step must not be blamed for
    hunting = reference_spec.with_parameters({"contact_equivalent_conicity": 0.9})
    assert step_is_stable(build_assembly(hunting), 83.33, 0.002)


def test_the_message_names_the_label_the_speed_and_the_minimum(reference_spec: RigSpec) -> None:
    problem = speed_problem(reference_spec, 5.0, speed_label="--speed")
    assert problem is not None
    assert problem.startswith("--speed: 5 m/s is not allowed: below the minimum speed 7.91 m/s")
    assert "time_step_s = 0.002 s" in problem
