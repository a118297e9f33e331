"""Generalised forces of all elements and the contact, in a few vectorised numpy calls.

Per step the world reads ``q, q̇`` (n,) once, this module turns them and the
track inputs ``x, ẋ`` (n_in,) into joint forces ``Q`` (n,) with two matrix
products (element coordinates in, generalised forces out) plus the nonlinear
force laws on the element vectors; the series-damper strokes advance with an
explicit Euler step (their relaxation is slow compared with the step).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.assembly import Assembly
from susp_bo.rig.elements import bilinear_force, bilinear_velocity, dead_band_force

FloatArray = NDArray[np.float64]


class ForceModel:
    """``Q(q, q̇, x, ẋ, V, s)`` for one assembly.

    Args:
        assembly: the vehicle.
        linear_elements: replace every nonlinear law by its slope at zero (bilinear
            dampers at the initial slope, dead bands at the slope at zero); used
            for the cross-check against the linearised model.
    """

    def __init__(self, assembly: Assembly, linear_elements: bool = False) -> None:
        groups = (assembly.springs.group, assembly.dead_bands.group, assembly.dampers.group,
                  assembly.series.group)
        sizes = [g.size for g in groups]
        edges = np.cumsum([0, *sizes])
        self.spring = slice(edges[0], edges[1])
        self.dead = slice(edges[1], edges[2])
        self.damper = slice(edges[2], edges[3])
        self.series = slice(edges[3], edges[4])
        g = np.vstack([grp.coordinates for grp in groups])
        h = np.vstack([grp.inputs for grp in groups])
        self.n = assembly.n_dofs
        self.n_in = assembly.n_inputs
        self.kinematics = np.ascontiguousarray(np.hstack([g, h]))  # (m x (n + n_in))
        self.transpose = np.ascontiguousarray(-g.T)  # (n x m): Q = -Gᵀ f
        contact = assembly.contact.matrices(self.n, self.n_in, 1.0)
        self.creep_stiffness = -np.hstack([contact["stiffness"], -contact["input_stiffness"]])
        self.creep_damping = -np.hstack([contact["damping"], -contact["input_damping"]])
        self.k_spring = assembly.springs.stiffness
        self.linear_elements = linear_elements
        dead = assembly.dead_bands
        self.dead_params = (dead.stiffness, dead.gap, dead.smoothing)
        self.k_dead_linear = dead.slope()
        dampers = assembly.dampers
        self.damper_params = (dampers.damping, dampers.slope_ratio, dampers.knee)
        series = assembly.series
        self.k_series = series.stiffness
        self.series_params = (series.damping, series.slope_ratio, series.knee)
        if linear_elements:
            ones = np.ones_like(series.damping)
            self.series_params = (series.damping, ones, np.full_like(ones, np.inf))
        self.state = np.zeros((self.n + self.n_in, 2))
        self.forces = np.zeros(g.shape[0])

    @property
    def n_strokes(self) -> int:
        """Number of series-damper strokes (internal states)."""
        return self.series.stop - self.series.start

    def __call__(self, q: FloatArray, qdot: FloatArray, x: FloatArray, xdot: FloatArray,
                 speed_m_s: float, stroke: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Generalised forces (n,) and stroke rates (n_s,) m/s.

        Args:
            q, qdot: coordinates and velocities (n,).
            x, xdot: track inputs and rates (n_in,).
            speed_m_s: speed (m/s).
            stroke: series-damper strokes (n_s,) m.
        """
        state = self.state
        n = self.n
        state[:n, 0] = q
        state[:n, 1] = qdot
        state[n:, 0] = x
        state[n:, 1] = xdot
        uv = self.kinematics @ state  # (m x 2): element coordinates and rates
        f = self.forces
        f[self.spring] = self.k_spring * uv[self.spring, 0]
        if self.linear_elements:
            f[self.dead] = self.k_dead_linear * uv[self.dead, 0]
            f[self.damper] = self.damper_params[0] * uv[self.damper, 1]
        else:
            f[self.dead] = dead_band_force(uv[self.dead, 0], *self.dead_params)
            f[self.damper] = bilinear_force(uv[self.damper, 1], *self.damper_params)
        series_force = self.k_series * (uv[self.series, 0] - stroke)
        f[self.series] = series_force
        generalised = (self.transpose @ f + self.creep_stiffness @ state[:, 0]
                       + self.creep_damping @ state[:, 1] / speed_m_s)
        return generalised, bilinear_velocity(series_force, *self.series_params)
