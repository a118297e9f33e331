"""The fused per-step force model against the element laws and the linearised matrices."""

from __future__ import annotations

import numpy as np

from susp_bo.rig.assembly import build_assembly
from susp_bo.rig.dynamics import ForceModel
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.state_space import state_space


def _random_state(assembly, rng, scale: float):
    n, n_in = assembly.n_dofs, assembly.n_inputs
    return (
        rng.normal(size=n) * scale,
        rng.normal(size=n) * 10 * scale,
        rng.normal(size=n_in) * scale,
        rng.normal(size=n_in) * 10 * scale,
        rng.normal(size=assembly.series.group.size) * scale,
    )


def test_linear_force_model_equals_the_state_space_rows(reference_spec: RigSpec, rng) -> None:
    assembly = build_assembly(reference_spec)
    speed = 83.33
    system = state_space(assembly, speed)
    q, qd, x, xd, stroke = _random_state(assembly, rng, 1e-2)
    generalised, rate = ForceModel(assembly, linear_elements=True)(q, qd, x, xd, speed, stroke)
    n = assembly.n_dofs
    state = np.concatenate([q, qd, stroke])
    derivative = system.a @ state + system.b @ x + system.b_rate @ xd
    np.testing.assert_allclose(
        generalised, assembly.mass_diagonal * derivative[n : 2 * n], rtol=1e-9, atol=1e-6
    )
    np.testing.assert_allclose(rate, derivative[2 * n :], rtol=1e-9, atol=1e-12)


def test_nonlinear_force_model_equals_the_element_laws(reference_spec: RigSpec, rng) -> None:
    assembly = build_assembly(reference_spec)
    speed = 60.0
    q, qd, x, xd, stroke = _random_state(assembly, rng, 2e-2)  # beyond knees and gaps
    generalised, rate = ForceModel(assembly)(q, qd, x, xd, speed, stroke)
    expected = np.zeros(assembly.n_dofs)
    for elements in (assembly.springs, assembly.dead_bands):
        g, h = elements.group.coordinates, elements.group.inputs
        expected -= g.T @ elements.force(g @ q + h @ x)
    g, h = assembly.dampers.group.coordinates, assembly.dampers.group.inputs
    expected -= g.T @ assembly.dampers.force(g @ qd + h @ xd)
    series = assembly.series
    g, h = series.group.coordinates, series.group.inputs
    force = series.force(g @ q + h @ x, stroke)
    expected -= g.T @ force
    lateral, moment = assembly.contact.creep_forces(q, qd, x, xd, speed)
    expected[assembly.contact.lateral_dof] += lateral
    expected[assembly.contact.yaw_dof] += moment
    np.testing.assert_allclose(generalised, expected, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(rate, series.stroke_rate(force), rtol=1e-12)


def _force_model_as_written(model: ForceModel, assembly, q, qd, x, xd, speed, stroke):
    """The per-step arithmetic in its plain form (np.clip, elements.dead_band_force, fresh
    arrays): what every recorded PyBullet figure was computed with before the step loop
    lost its temporaries."""
    from susp_bo.rig.elements import dead_band_force

    width = model.n + model.n_in
    z = np.concatenate([q, x, qd, xd, np.concatenate([qd, xd]) / speed])
    generalised = model.linear @ z
    nb, nd = model.n_bilinear, model.n_dead
    position = model.kinematics @ z[:width]
    f = np.zeros(model.kinematics.shape[0])
    argument = np.zeros(nb + model.n_series)
    argument[:nb] = model.kinematics[:nb] @ z[width : 2 * width]
    dead = assembly.dead_bands
    f[nb : nb + nd] = dead_band_force(
        position[nb : nb + nd], dead.stiffness, dead.gap, dead.smoothing
    )
    series_force = model.k_series * (position[nb + nd :] - stroke)
    f[nb + nd :] = series_force
    argument[nb:] = series_force
    scaled = argument * model.scale_in
    clipped = np.clip(scaled, -model.knee, model.knee)
    law = (clipped + model.slope * (scaled - clipped)) * model.scale_out
    f[:nb] = law[:nb]
    generalised += model.transpose @ f
    return generalised, law[nb:]


def test_the_step_loops_force_model_is_the_plain_arithmetic_bit_for_bit(
    reference_spec: RigSpec, rng
) -> None:
    """Buffers and fused calls must not move a last bit (every recorded figure rests on it):
    beyond the knees and gaps, at rest, and over repeated calls (buffers reused)."""
    assembly = build_assembly(reference_spec)
    model = ForceModel(assembly)
    assert model.n_bilinear > 0 and model.n_dead > 0 and model.n_series > 0
    for scale in (2e-2, 1e-4, 0.0, 5e-2):
        state = _random_state(assembly, rng, scale)
        got = model(*state[:4], 70.0, state[4])
        got = (got[0].copy(), got[1].copy())
        again = model(*state[:4], 70.0, state[4])
        expected = _force_model_as_written(model, assembly, *state[:4], 70.0, state[4])
        for a, b, c in zip(got, again, expected):
            assert np.array_equal(a, c) and np.array_equal(b, c)
