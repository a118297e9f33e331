"""The PyBullet world: joints are the generalised coordinates, no hidden damping or motors."""

from __future__ import annotations

import numpy as np
import pybullet
import pytest

from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.world import VehicleWorld


@pytest.fixture
def world(reference_spec: RigSpec):
    built = VehicleWorld(0.002)
    built.build(build_assembly(reference_spec))
    yield built
    built.close()


def _states(world: VehicleWorld) -> tuple[np.ndarray, np.ndarray]:
    states = world.client.getJointStates(world.body_id, world.joints)
    return np.array([s[0] for s in states]), np.array([s[1] for s in states])


def test_one_joint_per_coordinate_with_the_bodys_mass_and_inertia(
    world: VehicleWorld, reference_spec: RigSpec
) -> None:
    assembly = build_assembly(reference_spec)
    assert world.client.getNumJoints(world.body_id) == assembly.n_dofs
    torque = assembly.mass_diagonal * 0.5  # 0.5 m/s² or rad/s² on every coordinate
    steps = 100
    for _ in range(steps):
        world.client.setJointMotorControlArray(
            world.body_id, world.joints, pybullet.TORQUE_CONTROL, forces=torque
        )
        world.client.stepSimulation()
    _, velocity = _states(world)
    translations = [i for i, name in enumerate(assembly.dof_names) if name.endswith((".y", ".z"))]
    np.testing.assert_allclose(velocity[translations], 0.5 * steps * 0.002, rtol=1e-9)
    # rotations: Euler-angle coordinates, exact up to the small gyroscopic coupling
    np.testing.assert_allclose(velocity, 0.5 * steps * 0.002, rtol=2e-2)


def test_free_motion_keeps_its_velocity_no_damping_no_motors_no_gravity(
    world: VehicleWorld, reference_spec: RigSpec
) -> None:
    n = build_assembly(reference_spec).n_dofs
    initial = np.full(n, 0.01)
    world.set_state(np.zeros(n), initial)
    for _ in range(500):
        world.client.setJointMotorControlArray(
            world.body_id, world.joints, pybullet.TORQUE_CONTROL, forces=[0.0] * n
        )
        world.client.stepSimulation()
    position, velocity = _states(world)
    names = build_assembly(reference_spec).dof_names
    translations = [i for i, name in enumerate(names) if name.endswith((".y", ".z"))]
    np.testing.assert_allclose(velocity[translations], 0.01, rtol=1e-9)
    np.testing.assert_allclose(position[translations], 0.01 * 500 * 0.002, rtol=1e-9)
    # rotations: gyroscopic and Euler-rate coupling only (unequal principal inertias)
    np.testing.assert_allclose(velocity, 0.01, rtol=3e-2)


def test_close_is_idempotent(reference_spec: RigSpec) -> None:
    world = VehicleWorld(0.002)
    world.build(build_assembly(reference_spec))
    world.close()
    world.close()
