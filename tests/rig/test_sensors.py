"""Accelerometers: rigid-body kinematics, gravity pick-up through roll, boxcar sampling."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.rig.assembly import GRAVITY_M_S2, build_assembly
from susp_bo.rig.sensors import sample_decimated
from susp_bo.rig.spec import RigSpec


def test_static_roll_is_read_as_gravity_in_lateral_channels_only(reference_spec: RigSpec) -> None:
    assembly = build_assembly(reference_spec)
    n = assembly.n_dofs
    q = np.zeros((3, n))
    q[:, assembly.body("carbody").dofs[2]] = 0.01  # 10 mrad roll, at rest
    _, signals = sample_decimated(assembly, q, np.zeros((3, n)), 0.01)
    for c, name in enumerate(assembly.channels):
        expected = GRAVITY_M_S2 * 0.01 if name.startswith("carbody") and "lateral" in name else 0
        np.testing.assert_allclose(signals[c], expected, atol=1e-15)


def test_pitch_acceleration_reads_with_the_lever_arm(reference_spec: RigSpec) -> None:
    assembly = build_assembly(reference_spec)
    n = assembly.n_dofs
    pitch = assembly.body("carbody").dofs[3]
    t = np.arange(3) * 0.01
    qdot = np.zeros((3, n))
    qdot[:, pitch] = 2.0 * t  # pitch acceleration 2 rad/s²
    _, signals = sample_decimated(assembly, np.zeros((3, n)), qdot, 0.01)
    front = assembly.channels.index("carbody_front_vertical")
    mid = assembly.channels.index("carbody_mid_vertical")
    x_front = reference_spec.sensors[front].position_m[0]
    # nose-down pitch (+ about y) moves the front sensor down
    np.testing.assert_allclose(signals[front], -2.0 * x_front)
    np.testing.assert_allclose(signals[mid], 0.0, atol=1e-15)


def test_samples_are_interval_means(reference_spec: RigSpec) -> None:
    assembly = build_assembly(reference_spec)
    n = assembly.n_dofs
    z = assembly.body("carbody").dofs[1]
    interval = 0.01
    t = np.arange(101) * interval
    frequency = 3.0
    qdot = np.zeros((t.size, n))
    qdot[:, z] = np.sin(2 * np.pi * frequency * t)
    time, signals = sample_decimated(assembly, np.zeros_like(qdot), qdot, interval)
    mid = assembly.channels.index("carbody_mid_vertical")
    exact = 2 * np.pi * frequency * np.cos(2 * np.pi * frequency * time)
    np.testing.assert_allclose(signals[mid], exact * np.sinc(frequency * interval), atol=1e-9)
    assert time[0] == pytest.approx(0.5 * interval)
