"""Wheel–rail contact: linear Kalker creep with equivalent conicity, smoothed flange dead band.

Each wheelset has two dynamic coordinates, lateral displacement ``y`` (m, + left)
and yaw ``ψ`` (rad); its vertical motion and roll follow the rails (prescribed
by the track inputs). With ``Δy = y - y_track`` (alignment under the axle), the
speed ``V``, half contact spacing ``b``, rolling radius ``r0``, equivalent
conicity ``λ`` and creep coefficients ``f11`` (longitudinal), ``f22`` (lateral):

    lateral creep force   F_y = -2 f22 (Δẏ / V - ψ) - F_flange(Δy)
    yaw creep moment      M_z = -2 f11 b (b ψ̇ / V + λ Δy / r0)

(Wickens' linear wheelset; spin creep and gravitational stiffness neglected).
Without inertia and suspension this gives Klingel's kinematic oscillation of
wavelength ``2π √(r0 b / λ)``. The flange is a smoothed dead band of
clearance ``flange_gap`` and stiffness ``flange_stiffness`` on ``Δy``; it is built
as an element of the dead-band group (see assembly.py) so that both the
PyBullet world and the linearised model use it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


def klingel_wavelength(
    rolling_radius_m: float, half_contact_spacing_m: float, conicity: float
) -> float:
    """Kinematic (Klingel) wavelength ``2π √(r0 b / λ)`` (m)."""
    return 2.0 * math.pi * math.sqrt(rolling_radius_m * half_contact_spacing_m / conicity)


@dataclass(frozen=True)
class WheelRailContact:
    """Linear creep forces of n_w wheelsets (the flange is a dead-band element group).

    Args:
        lateral_dof: index of each wheelset's lateral coordinate in q, (n_w,).
        yaw_dof: index of each wheelset's yaw coordinate in q, (n_w,).
        alignment_input: index of each wheelset's alignment input in x(t), (n_w,).
        longitudinal_creep: f11 (N).
        lateral_creep: f22 (N).
        conicity: equivalent conicity λ (-).
        rolling_radius: r0 (m).
        half_contact_spacing: b (m).
    """

    lateral_dof: IntArray
    yaw_dof: IntArray
    alignment_input: IntArray
    longitudinal_creep: float
    lateral_creep: float
    conicity: float
    rolling_radius: float
    half_contact_spacing: float

    def creep_forces(
        self, q: FloatArray, qdot: FloatArray, x: FloatArray, xdot: FloatArray, speed_m_s: float
    ) -> tuple[FloatArray, FloatArray]:
        """Creep lateral forces (N) and yaw moments (N·m) on the wheelsets, each (n_w,).

        Args:
            q, qdot: generalised coordinates and velocities (n,).
            x, xdot: track inputs and rates (n_in,).
            speed_m_s: train speed (m/s), > 0.
        """
        relative = q[self.lateral_dof] - x[self.alignment_input]
        relative_rate = qdot[self.lateral_dof] - xdot[self.alignment_input]
        b = self.half_contact_spacing
        lateral = -2.0 * self.lateral_creep * (relative_rate / speed_m_s - q[self.yaw_dof])
        moment = (
            -2.0
            * self.longitudinal_creep
            * b
            * (b * qdot[self.yaw_dof] / speed_m_s + self.conicity * relative / self.rolling_radius)
        )
        return lateral, moment

    def matrices(self, n: int, n_in: int, speed_m_s: float) -> dict[str, FloatArray]:
        """Creep forces as ``Q = -K q - C q̇ + K_in x + C_in ẋ`` at speed ``speed_m_s``.

        Returns:
            ``stiffness`` (n x n, not symmetric), ``damping`` (n x n),
            ``input_stiffness`` (n x n_in), ``input_damping`` (n x n_in). Damping
            terms scale with 1 / speed.
        """
        k = np.zeros((n, n))
        c = np.zeros((n, n))
        k_in = np.zeros((n, n_in))
        c_in = np.zeros((n, n_in))
        b = self.half_contact_spacing
        yaw_coupling = 2.0 * self.longitudinal_creep * b * self.conicity / self.rolling_radius
        for y, psi, a in zip(self.lateral_dof, self.yaw_dof, self.alignment_input):
            c[y, y] += 2.0 * self.lateral_creep / speed_m_s
            c[psi, psi] += 2.0 * self.longitudinal_creep * b * b / speed_m_s
            k[y, psi] -= 2.0 * self.lateral_creep
            k[psi, y] += yaw_coupling
            c_in[y, a] += 2.0 * self.lateral_creep / speed_m_s
            k_in[psi, a] += yaw_coupling
        return {"stiffness": k, "damping": c, "input_stiffness": k_in, "input_damping": c_in}
