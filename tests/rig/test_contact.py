"""Wheel–rail contact: Klingel's kinematic oscillation, creep forces vs their matrices."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.rig.assembly import build_assembly, free_wheelset_assembly
from susp_bo.rig.contact import klingel_wavelength
from susp_bo.rig.dynamics import ForceModel
from susp_bo.rig.simulator import integrate
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.state_space import state_space
from susp_bo.rig.track import AxleExcitation
from susp_bo.rig.world import VehicleWorld


def test_single_wheelset_oscillates_at_klingels_wavelength_in_pybullet(
    reference_spec: RigSpec,
) -> None:
    p = reference_spec.parameters
    expected = klingel_wavelength(
        p["wheelset_rolling_radius"],
        p["contact_half_contact_spacing"],
        p["contact_equivalent_conicity"],
    )
    assembly = free_wheelset_assembly(reference_spec)
    speed, dt, steps = 10.0, 5e-4, 6000
    zeros = np.zeros((1, steps + 1))
    excitation = AxleExcitation(np.arange(steps + 1) * dt, *([zeros] * 7))
    world = VehicleWorld(dt)
    try:
        world.build(assembly)
        world.set_state([0.003, 0.0], [0.0, 0.0])
        q, _ = integrate(
            world,
            ForceModel(assembly),
            excitation,
            np.full(steps + 1, speed),
            1,
            0.2,
            assembly.dof_names,
        )
    finally:
        world.close()
    y = q[:, 0]
    t = np.arange(steps + 1) * dt
    i = np.where(np.sign(y[:-1]) * np.sign(y[1:]) < 0)[0]
    crossings = t[i] - y[i] * dt / (y[i + 1] - y[i])
    wavelength = speed * 2 * np.mean(np.diff(crossings))
    assert wavelength == pytest.approx(expected, rel=0.005)
    # the linearised model of the same assembly agrees
    values = np.linalg.eigvals(state_space(assembly, speed).a)
    oscillatory = values[values.imag > 0]
    assert speed * 2 * np.pi / oscillatory.imag[0] == pytest.approx(expected, rel=0.005)


def test_creep_forces_equal_their_linear_matrices(reference_spec: RigSpec, rng) -> None:
    assembly = build_assembly(reference_spec)
    contact = assembly.contact
    n, n_in = assembly.n_dofs, assembly.n_inputs
    q, qd = rng.normal(size=n) * 1e-3, rng.normal(size=n) * 1e-2
    x, xd = rng.normal(size=n_in) * 1e-3, rng.normal(size=n_in) * 1e-2
    speed = 70.0
    lateral, moment = contact.creep_forces(q, qd, x, xd, speed)
    m = contact.matrices(n, n_in, speed)
    generalised = (
        -m["stiffness"] @ q - m["damping"] @ qd + m["input_stiffness"] @ x + m["input_damping"] @ xd
    )
    np.testing.assert_allclose(generalised[contact.lateral_dof], lateral, rtol=1e-12)
    np.testing.assert_allclose(generalised[contact.yaw_dof], moment, rtol=1e-12)


def test_flange_dead_band_only_acts_beyond_the_clearance(reference_spec: RigSpec) -> None:
    assembly = build_assembly(reference_spec)
    dead = assembly.dead_bands
    row = dead.group.names.index("flange_wheelset_1")
    lateral = assembly.contact.lateral_dof[0]
    alignment = assembly.contact.alignment_input[0]
    # the element coordinate is the wheelset's offset from the track centre line
    assert dead.group.coordinates[row, lateral] == 1.0
    assert dead.group.inputs[row, alignment] == -1.0
    assert np.count_nonzero(dead.group.coordinates[row]) == 1
    gap = reference_spec.parameters["contact_flange_gap"]
    stiffness = reference_spec.parameters["contact_flange_stiffness"]

    def flange(offset: float) -> float:
        return float(dead.force(np.full(dead.group.size, offset))[row])

    assert abs(flange(0.5 * gap)) < 2e-3 * stiffness * gap  # 0.2 % of a full-stiffness force
    assert flange(gap + 0.005) == pytest.approx(stiffness * 0.005, rel=0.01)
    assert flange(-gap - 0.005) == pytest.approx(-stiffness * 0.005, rel=0.01)
