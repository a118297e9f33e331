"""The assembly builder: bodies, coordinates and element rows, before they become an Assembly.

:func:`susp_bo.rig.assembly.build_assembly` fills an :class:`AssemblyBuilder`
with the vehicle's bodies and force elements, then every switched-on effect
(:mod:`susp_bo.rig.effects`) extends it — adding bodies (e.g. a modal
coordinate), element rows, point kinematics or periodic inputs — before the
builder is frozen into the :class:`~susp_bo.rig.assembly.Assembly` that both the
PyBullet world and the linearised model use.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.elements import ElementGroup

FloatArray = NDArray[np.float64]
RIGID_DOFS = ("y", "z", "roll", "pitch", "yaw")
WHEELSET_DOFS = ("y", "yaw")
MODAL_DOFS = ("eta",)
DOFS_OF_KIND = {"rigid": RIGID_DOFS, "wheelset": WHEELSET_DOFS, "modal": MODAL_DOFS}
PointTerm = Callable[[str, tuple[float, float, float], str], dict[int, float]]
"""``term(body, location, axis) -> {dof index: coefficient}``: extra kinematics of body points."""


@dataclass(frozen=True)
class Body:
    """A body of the vehicle.

    Args:
        name: e.g. ``carbody``, ``bogie_front``, ``wheelset_1``, ``carbody_bending``.
        kind: ``rigid`` (5 coordinates), ``wheelset`` (lateral and yaw) or ``modal``
            (one elastic modal coordinate ``eta`` of generalised mass ``mass``; added
            by effects such as carbody bending).
        cg_m: nominal centre of gravity (x, y, z) in vehicle coordinates, m.
        mass: kg.
        inertia: principal moments (roll, pitch, yaw), kg·m².
        dofs: indices of its coordinates in q.
    """

    name: str
    kind: str
    cg_m: tuple[float, float, float]
    mass: float
    inertia: tuple[float, float, float]
    dofs: tuple[int, ...]


@dataclass(frozen=True)
class PeriodicInputs:
    """Deterministic periodic inputs ``x_i(t) += A cos(k s(t) + φ)`` (wheel out-of-roundness).

    Attributes:
        input_index: index i in the track-input vector x (m,).
        amplitude: A (m or rad) (m,).
        wavenumber_rad_m: k, rad per metre travelled (m,); frequency ``k V / 2π`` Hz.
        phase_rad: φ (m,).
    """

    input_index: NDArray[np.intp]
    amplitude: FloatArray
    wavenumber_rad_m: FloatArray
    phase_rad: FloatArray

    @staticmethod
    def empty() -> PeriodicInputs:
        """No periodic inputs."""
        return PeriodicInputs(np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0), np.zeros(0))

    @property
    def size(self) -> int:
        """Number of periodic inputs m."""
        return int(self.amplitude.size)

    def values(self, distance_m: FloatArray, n_inputs: int) -> FloatArray:
        """Input additions (n_inputs x n_t) at travelled distances ``distance_m`` (n_t,) m."""
        out = np.zeros((n_inputs, np.size(distance_m)))
        for i, a, k, phi in zip(
            self.input_index, self.amplitude, self.wavenumber_rad_m, self.phase_rad
        ):
            out[i] += a * np.cos(k * distance_m + phi)
        return out

    def rates(self, distance_m: FloatArray, speed_m_s: FloatArray, n_inputs: int) -> FloatArray:
        """Time derivatives of :meth:`values` (n_inputs x n_t), at speeds (n_t,) m/s."""
        out = np.zeros((n_inputs, np.size(distance_m)))
        for i, a, k, phi in zip(
            self.input_index, self.amplitude, self.wavenumber_rad_m, self.phase_rad
        ):
            out[i] -= a * k * speed_m_s * np.sin(k * distance_m + phi)
        return out


class AssemblyBuilder:
    """Collects element rows from (location, direction, body pair) descriptions."""

    def __init__(self, bodies: list[Body], n_inputs: int) -> None:
        self.bodies = {b.name: b for b in bodies}
        self.n = sum(len(b.dofs) for b in bodies)
        self.n_inputs = n_inputs
        self.axle_of: dict[str, int] = {}
        self.rows: dict[str, list[tuple[str, FloatArray, FloatArray, dict[str, float]]]] = {}
        # (kind, row index) -> (lower, upper, location, axis) for rows built by add()
        self.placement: dict[tuple[str, int], tuple[str, str, tuple[float, float, float], str]] = {}
        self.point_terms: list[PointTerm] = []
        self.periodic: list[tuple[int, float, float, float]] = []

    def add_body(self, body: Body) -> int:
        """Append a body (its ``dofs`` are assigned here); returns its first coordinate index.

        Every existing element row is padded with zeros for the new coordinates.
        """
        if body.name in self.bodies:
            raise ValueError(f"body {body.name!r} already exists")
        count = len(DOFS_OF_KIND[body.kind])
        first = self.n
        self.bodies[body.name] = Body(
            body.name,
            body.kind,
            body.cg_m,
            body.mass,
            body.inertia,
            tuple(range(first, first + count)),
        )
        self.n += count
        for kind, rows in self.rows.items():
            self.rows[kind] = [
                (name, np.concatenate([g, np.zeros(count)]), h, params)
                for name, g, h, params in rows
            ]
        return first

    def add_point_term(self, term: PointTerm) -> None:
        """Register extra kinematics of body points and re-derive every placed element."""
        self.point_terms.append(term)
        for (kind, index), (lower, upper, location, axis) in self.placement.items():
            name, _, _, params = self.rows[kind][index]
            g_up, h_up = self.point_rows(upper, location, axis)
            g_lo, h_lo = self.point_rows(lower, location, axis)
            self.rows[kind][index] = (name, g_up - g_lo, h_up - h_lo, params)

    def add_periodic_input(
        self, input_index: int, amplitude: float, wavenumber_rad_m: float, phase_rad: float
    ) -> None:
        """A deterministic input ``x_i += A cos(k s + φ)`` (see :class:`PeriodicInputs`)."""
        self.periodic.append(
            (int(input_index), float(amplitude), float(wavenumber_rad_m), float(phase_rad))
        )

    def element_params(self, kind: str, prefix: str) -> list[dict[str, float]]:
        """The (mutable) parameter dicts of the rows of ``kind`` whose name starts with prefix."""
        return [row[3] for row in self.rows.get(kind, []) if row[0].startswith(prefix)]

    def point_rows(
        self, body_name: str, location: tuple[float, float, float], axis: str
    ) -> tuple[FloatArray, FloatArray]:
        """Small displacement of a body point along a world axis: (n,) on q, (n_in,) on x."""
        body = self.bodies[body_name]
        g = np.zeros(self.n)
        h = np.zeros(self.n_inputs)
        rx, ry, rz = (location[i] - body.cg_m[i] for i in range(3))
        if body.kind == "rigid":
            y, z, roll, pitch, yaw = body.dofs
            coefficients = {
                "x": {pitch: rz, yaw: -ry},
                "y": {y: 1.0, roll: -rz, yaw: rx},
                "z": {z: 1.0, roll: ry, pitch: -rx},
            }[axis]
            for index, value in coefficients.items():
                g[index] += value
            for term in self.point_terms:
                for index, value in term(body_name, location, axis).items():
                    g[index] += value
        elif body.kind == "modal":
            raise ValueError(f"body {body_name!r} is a modal coordinate; it has no points")
        else:
            y, yaw = body.dofs
            axle = self.axle_of[body_name]
            vertical, cross_level = 3 * axle, 3 * axle + 1
            if axis == "x":
                g[yaw] -= ry
            elif axis == "y":
                g[y] += 1.0
                g[yaw] += rx
                h[cross_level] -= rz
            else:
                h[vertical] += 1.0
                h[cross_level] += ry
        return g, h

    def add(
        self,
        kind: str,
        name: str,
        lower: str,
        upper: str,
        location: tuple[float, float, float],
        axis: str,
        **params: float,
    ) -> None:
        """An element between ``lower`` and ``upper`` at ``location`` along world ``axis``."""
        g_up, h_up = self.point_rows(upper, location, axis)
        g_lo, h_lo = self.point_rows(lower, location, axis)
        rows = self.rows.setdefault(kind, [])
        self.placement[kind, len(rows)] = (lower, upper, location, axis)
        rows.append((name, g_up - g_lo, h_up - h_lo, params))

    def add_rows(self, kind: str, name: str, g: FloatArray, h: FloatArray, **params: float) -> None:
        """An element with explicit kinematic rows."""
        self.rows.setdefault(kind, []).append((name, g, h, params))

    def group(self, kind: str) -> tuple[ElementGroup, dict[str, FloatArray]]:
        """The rows of one kind as an ElementGroup plus stacked parameter arrays."""
        rows = self.rows.get(kind, [])
        names = tuple(r[0] for r in rows)
        g = np.array([r[1] for r in rows]).reshape(len(rows), self.n)
        h = np.array([r[2] for r in rows]).reshape(len(rows), self.n_inputs)
        keys = rows[0][3].keys() if rows else ()
        params = {k: np.array([r[3][k] for r in rows], dtype=np.float64) for k in keys}
        return ElementGroup(names, g, h), params
