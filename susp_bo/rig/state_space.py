"""The linearised equations of motion of a rig assembly, and its sensors' transfer functions.

The mass, damping and stiffness matrices are ``Σ Gᵀ diag(slope) G`` over the element
groups of an :class:`~susp_bo.rig.assembly.Assembly` (bilinear dampers at their initial
slope, dead bands at their slope at zero or at a given operating point), plus the
linear wheel–rail contact at speed V, and the series spring–damper strokes as
first-order states: ``ż = A z + B x + B_d ẋ`` with ``z = [q, q̇, s]``
(:func:`state_space`). :func:`sensor_transfer` gives every sensor's response to unit
harmonic track inputs, per frequency. :class:`~susp_bo.rig.linear.LinearisedRig`
builds its spectra, time responses and modes on these.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.assembly import Assembly

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]


@dataclass(frozen=True)
class StateSpace:
    """``ż = A z + B x + B_d ẋ``, sensors ``y = C_a q̈ + C_d q`` (see module docstring)."""

    a: FloatArray
    b: FloatArray
    b_rate: FloatArray
    n_dofs: int
    assembly: Assembly


def state_space(
    assembly: Assembly, speed_m_s: float, dead_band_slopes: FloatArray | None = None
) -> StateSpace:
    """Linearise an assembly about the static equilibrium at speed ``speed_m_s`` (m/s).

    Args:
        assembly: the vehicle.
        speed_m_s: speed (m/s), > 0.
        dead_band_slopes: slopes (N/m) of the dead bands at the operating point
            (m_dead,), e.g. about a steady curving state
            (:func:`~susp_bo.rig.linear_curving.operating_points`); None: at u = 0.
    """
    if not speed_m_s > 0:
        raise ValueError(f"speed_m_s: got {speed_m_s}; must be > 0 m/s")
    n, n_in = assembly.n_dofs, assembly.n_inputs
    k = np.zeros((n, n))
    c = np.zeros((n, n))
    k_in = np.zeros((n, n_in))
    c_in = np.zeros((n, n_in))
    for elements in (assembly.springs, assembly.dead_bands):
        g, h, slope = elements.group.coordinates, elements.group.inputs, elements.slope()
        if dead_band_slopes is not None and elements is assembly.dead_bands:
            slope = np.asarray(dead_band_slopes, dtype=np.float64)
        k += g.T @ (slope[:, None] * g)
        k_in -= g.T @ (slope[:, None] * h)
    g, h, slope = (
        assembly.dampers.group.coordinates,
        assembly.dampers.group.inputs,
        assembly.dampers.slope(),
    )
    c += g.T @ (slope[:, None] * g)
    c_in -= g.T @ (slope[:, None] * h)
    contact = assembly.contact.matrices(n, n_in, speed_m_s)
    k += contact["stiffness"]
    c += contact["damping"]
    k_in += contact["input_stiffness"]
    c_in += contact["input_damping"]
    series = assembly.series
    gs, hs, ks, cs = series.group.coordinates, series.group.inputs, series.stiffness, series.damping
    n_s = series.group.size
    k += gs.T @ (ks[:, None] * gs)
    k_in -= gs.T @ (ks[:, None] * hs)
    m_inv = 1.0 / assembly.mass_diagonal
    size = 2 * n + n_s
    a = np.zeros((size, size))
    a[:n, n : 2 * n] = np.eye(n)
    a[n : 2 * n, :n] = -m_inv[:, None] * k
    a[n : 2 * n, n : 2 * n] = -m_inv[:, None] * c
    a[n : 2 * n, 2 * n :] = m_inv[:, None] * (gs.T * ks[None, :])  # + Gᵀ k_s s
    rate = (ks / cs)[:, None]
    a[2 * n :, :n] = rate * gs
    a[2 * n :, 2 * n :] = -np.diag(ks / cs)
    b = np.zeros((size, n_in))
    b_rate = np.zeros((size, n_in))
    b[n : 2 * n] = m_inv[:, None] * k_in
    b_rate[n : 2 * n] = m_inv[:, None] * c_in
    b[2 * n :] = rate * hs
    return StateSpace(a, b, b_rate, n, assembly)


def sensor_transfer(
    system: StateSpace,
    frequencies_hz: FloatArray,
    sample_rate_hz: float | None = None,
    method: str = "modal",
) -> ComplexArray:
    """Sensor response to unit harmonic inputs: (F x C x n_in), (m/s²) per input unit.

    Args:
        system: the linearised rig.
        frequencies_hz: (F,) Hz.
        sample_rate_hz: when given, the sensor model of the time-domain rig is
            included: accelerations averaged over one sample interval (sinc) and
            gravity pick-up averaged over its end points (cosine).
        method: ``modal`` (diagonalise A once: fast) or ``solve`` (one linear
            solve per frequency: the reference).
    """
    f = np.asarray(frequencies_hz, dtype=np.float64)
    omega = 2.0 * np.pi * f
    n = system.n_dofs
    acc_rows = system.assembly.sensor_acceleration
    disp_rows = system.assembly.sensor_displacement
    acc_gain = 1j * omega
    disp_gain = np.ones_like(omega)
    if sample_rate_hz is not None:
        acc_gain = acc_gain * np.sinc(f / sample_rate_hz)
        disp_gain = disp_gain * np.cos(np.pi * f / sample_rate_hz)
    if method == "modal":
        values, vectors = np.linalg.eig(system.a)
        inverse = np.linalg.inv(vectors)
        forcing = inverse @ system.b  # (N x n_in)
        forcing_rate = inverse @ system.b_rate
        out_acc = acc_rows @ vectors[n : 2 * n]  # (C x N)
        out_disp = disp_rows @ vectors[:n]
        response = 1.0 / (1j * omega[:, None] - values[None, :])  # (F x N)
        outputs = (
            acc_gain[:, None, None] * out_acc[None] + disp_gain[:, None, None] * out_disp[None]
        ) * response[:, None, :]  # (F x C x N)
        return outputs @ forcing + (1j * omega)[:, None, None] * (outputs @ forcing_rate)
    if method != "solve":
        raise ValueError(f"sensor_transfer.method: got {method!r}; allowed 'modal', 'solve'")
    size = system.a.shape[0]
    lhs = 1j * omega[:, None, None] * np.eye(size)[None] - system.a[None]
    rhs = system.b[None] + 1j * omega[:, None, None] * system.b_rate[None]
    z = np.linalg.solve(lhs, rhs)  # (F x size x n_in)
    acc_part = np.einsum("cn,fni->fci", acc_rows, z[:, n : 2 * n]) * acc_gain[:, None, None]
    disp_part = np.einsum("cn,fni->fci", disp_rows, z[:, :n]) * disp_gain[:, None, None]
    return acc_part + disp_part
