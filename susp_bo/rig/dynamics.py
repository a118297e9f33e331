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

FloatArray = NDArray[np.float64]


class ForceModel:
    """``Q(q, q̇, x, ẋ, V, s)`` for one assembly.

    Elements whose law is linear (springs, dampers without a knee) and the creep
    forces are folded into one matrix acting on ``[q, x, q̇, ẋ, (q̇, ẋ)/V]``; only
    the nonlinear elements (bilinear dampers, dead bands, series dampers) are
    evaluated element by element, all bilinear laws in one vectorised call.

    Args:
        assembly: the vehicle.
        linear_elements: replace every nonlinear law by its slope at zero (bilinear
            dampers at the initial slope, dead bands at the slope at zero); used
            for the cross-check against the linearised model.
    """

    def __init__(self, assembly: Assembly, linear_elements: bool = False) -> None:
        self.n = n = assembly.n_dofs
        self.n_in = assembly.n_inputs
        width = n + self.n_in
        springs, dead, dampers, series = (
            assembly.springs,
            assembly.dead_bands,
            assembly.dampers,
            assembly.series,
        )

        def rows(group: object) -> FloatArray:
            return np.hstack([group.coordinates, group.inputs])  # type: ignore[attr-defined]

        bilinear = (dampers.knee < np.inf) & (dampers.slope_ratio != 1.0) & (not linear_elements)
        stiffness = rows(springs.group).T @ (springs.stiffness[:, None] * rows(springs.group))
        damper_rows = rows(dampers.group)
        linear_c = np.where(bilinear, 0.0, dampers.damping)
        damping = damper_rows.T @ (linear_c[:, None] * damper_rows)
        if linear_elements:
            dead_rows = rows(dead.group)
            stiffness += dead_rows.T @ (dead.slope()[:, None] * dead_rows)
        contact = assembly.contact.matrices(n, self.n_in, 1.0)
        creep_k = np.hstack([contact["stiffness"], -contact["input_stiffness"]])
        creep_c = np.hstack([contact["damping"], -contact["input_damping"]])
        # Q_linear = L @ [z, ż, ż / V] with z = [q, x]
        self.linear = np.ascontiguousarray(
            -np.hstack([stiffness[:n] + creep_k, damping[:n], creep_c])
        )
        # the linear elements alone (no creep), for the design offsets of a curved line
        self.elastic = np.ascontiguousarray(-stiffness[:n].T)  # (width x n)
        self.viscous = np.ascontiguousarray(-damping[:n].T)
        self.stacked = np.zeros(3 * width)
        # nonlinear rows: [bilinear dampers (velocity), dead bands (position), series (position)]
        self.dead_on = not linear_elements and dead.group.size > 0
        nonlinear = [damper_rows[bilinear]]
        if self.dead_on:
            nonlinear.append(rows(dead.group))
        nonlinear.append(rows(series.group))
        g_nl = np.vstack(nonlinear)
        self.n_bilinear = int(bilinear.sum())
        self.n_dead = dead.group.size if self.dead_on else 0
        self.n_series = series.group.size
        self.kinematics = np.ascontiguousarray(g_nl)  # (m_nl x width)
        self.transpose = np.ascontiguousarray(-g_nl[:, :n].T)  # (n x m_nl)
        self.k_series = series.stiffness
        # one bilinear evaluation for dampers (v -> f / c) and series strokes (f / c -> v):
        # out = clip(a, ±knee) + slope · (a - clip), then scaled
        series_ratio = np.ones(self.n_series) if linear_elements else series.slope_ratio
        series_knee = np.full(self.n_series, np.inf) if linear_elements else series.knee
        self.knee = np.concatenate([dampers.knee[bilinear], series_knee])
        self.slope = np.concatenate([dampers.slope_ratio[bilinear], 1.0 / series_ratio])
        self.scale_in = np.concatenate([np.ones(self.n_bilinear), 1.0 / series.damping])
        self.scale_out = np.concatenate([dampers.damping[bilinear], np.ones(self.n_series)])
        self.argument = np.zeros(self.n_bilinear + self.n_series)
        self.forces = np.zeros(g_nl.shape[0])
        # per-step work buffers and constants (the step loop's arithmetic, op for op, with
        # fewer temporaries: np.clip(a, -k, k) is minimum(maximum(a, -k), k) bit for bit)
        self._negative_knee = -self.knee
        self._scaled = np.zeros_like(self.argument)
        self._clipped = np.zeros_like(self.argument)
        self._bilinear_kinematics = self.kinematics[: self.n_bilinear]
        self._dead_stiffness_smoothing = dead.stiffness * dead.smoothing
        self._dead_gap, self._dead_smoothing = dead.gap, dead.smoothing

    def design_forces(self, offsets: FloatArray, rates: FloatArray) -> FloatArray:
        """Generalised forces of the linear elements on design offsets, (T x n).

        Args:
            offsets: ``[d, x_d]`` reference poses (T x (n + n_in)), see :mod:`susp_bo.rig.curving`.
            rates: their time derivatives (T x (n + n_in)).
        """
        return offsets @ self.elastic + rates @ self.viscous

    def series_positions(self, z: FloatArray) -> FloatArray:
        """Series-element deflections (n_s,) for ``[q, x]`` plus design offsets (n + n_in,)."""
        nb, nd = self.n_bilinear, self.n_dead
        return self.kinematics[nb + nd :] @ z

    @property
    def n_strokes(self) -> int:
        """Number of series-damper strokes (internal states)."""
        return self.n_series

    def __call__(
        self,
        q: FloatArray,
        qdot: FloatArray,
        x: FloatArray,
        xdot: FloatArray,
        speed_m_s: float,
        stroke: FloatArray,
        offset: FloatArray | None = None,
        offset_rate: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray]:
        """Generalised forces (n,) and stroke rates (n_s,) m/s.

        Args:
            q, qdot: coordinates and velocities (n,).
            x, xdot: track inputs and rates (n_in,).
            speed_m_s: speed (m/s).
            stroke: series-damper strokes (n_s,) m.
            offset, offset_rate: design offsets ``[d, x_d]`` and rates (n + n_in,) seen by
                the nonlinear elements (a curved line); the linear elements' share is
                :meth:`design_forces`, added by the caller. None on tangent track.
        """
        z = self.stacked
        n, width = self.n, self.n + self.n_in
        z[:n] = q
        z[n:width] = x
        z[width : width + n] = qdot
        z[width + n : 2 * width] = xdot
        np.divide(z[width : 2 * width], speed_m_s, out=z[2 * width :])
        generalised = self.linear @ z
        nb, nd = self.n_bilinear, self.n_dead
        if offset is None:
            position = self.kinematics @ z[:width]
        else:
            position = self.kinematics @ (z[:width] + offset)
        f = self.forces
        argument = self.argument
        if offset_rate is None:
            argument[:nb] = self._bilinear_kinematics @ z[width : 2 * width]
        else:
            argument[:nb] = self._bilinear_kinematics @ (z[width : 2 * width] + offset_rate)
        if nd:
            # elements.dead_band_force, op for op: k s (softplus((u - g)/s) - softplus((-u - g)/s))
            u, gap, smoothing = position[nb : nb + nd], self._dead_gap, self._dead_smoothing
            np.multiply(
                self._dead_stiffness_smoothing,
                np.logaddexp(0.0, (u - gap) / smoothing)
                - np.logaddexp(0.0, (-u - gap) / smoothing),
                out=f[nb : nb + nd],
            )
        series_force = f[nb + nd :]
        np.multiply(self.k_series, position[nb + nd :] - stroke, out=series_force)
        argument[nb:] = series_force
        scaled = np.multiply(argument, self.scale_in, out=self._scaled)
        clipped = np.minimum(
            np.maximum(scaled, self._negative_knee, out=self._clipped), self.knee, out=self._clipped
        )
        law = (clipped + self.slope * (scaled - clipped)) * self.scale_out
        f[:nb] = law[:nb]
        generalised += self.transpose @ f
        return generalised, law[nb:]
