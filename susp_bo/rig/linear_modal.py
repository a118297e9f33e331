"""The linearised rig in modal coordinates: eigen-decomposition, modal solve, named modes.

The state matrix of :class:`~susp_bo.rig.state_space.StateSpace` is decomposed once per
system, ``A = V diag(λ) V⁻¹`` (:func:`_modal_basis`, state size x state size); output
spectra ``rows · z(ω)`` (m x F) are then solved mode by mode (:func:`_solve_outputs`),
one solve per frequency when V is ill-conditioned. A mode (:class:`Mode`) is named by
the (body kind, coordinate) with the largest share of its energy (:func:`_label`:
``bogie_front.z`` -> ``bogie_bounce``). Used by :class:`~susp_bo.rig.linear.LinearisedRig`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.state_space import StateSpace

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
_COORDINATE_MEANING = {
    "y": "lateral",
    "z": "bounce",
    "roll": "roll",
    "pitch": "pitch",
    "yaw": "yaw",
    "eta": "bending",
}


@dataclass(frozen=True)
class Mode:
    """A mode of the linearised vehicle: name by dominant motion, frequency, damping ratio."""

    name: str
    frequency_hz: float
    damping_ratio: float
    energy_share: float


@dataclass(frozen=True)
class _ModalBasis:
    """``A = V diag(λ) V⁻¹``: eigenvalues (size,), eigenvectors V and V⁻¹ (size x size),
    and whether V is well-conditioned enough to solve in modal coordinates."""

    values: ComplexArray
    vectors: ComplexArray
    inverse: ComplexArray
    well_conditioned: bool


def _modal_basis(system: StateSpace) -> _ModalBasis:
    """Eigen-decomposition of the state matrix, with its conditioning verdict."""
    values, vectors = np.linalg.eig(system.a)
    inverse = np.linalg.inv(vectors)
    well = bool(np.max(np.abs(inverse)) * np.max(np.abs(vectors)) < 1e8)
    return _ModalBasis(values, vectors, inverse, well)


def _solve_outputs(
    system: StateSpace,
    basis: _ModalBasis,
    rows: FloatArray,
    spectrum: ComplexArray,
    rate_spectrum: ComplexArray,
    omega: FloatArray,
) -> ComplexArray:
    """Output spectra ``rows · z(ω)`` (m x F) of ``(iω - A) z = B X + B_d Ẋ``.

    Solves in the modal coordinates of ``basis`` (fast); falls back to one solve per
    frequency when the eigenvectors are ill-conditioned.
    """
    values, vectors, inverse = basis.values, basis.vectors, basis.inverse
    if basis.well_conditioned:
        modal = (inverse @ system.b) @ spectrum + (inverse @ system.b_rate) @ rate_spectrum
        modal /= 1j * omega[None, :] - values[:, None]
        return (rows @ vectors) @ modal
    forcing = system.b @ spectrum + system.b_rate @ rate_spectrum  # (size x F)
    size = system.a.shape[0]
    lhs = 1j * omega[:, None, None] * np.eye(size)[None] - system.a[None]
    states = np.linalg.solve(lhs, forcing.T[:, :, None])[:, :, 0].T
    return rows @ states


def _label(dof_name: str) -> str:
    """``bogie_front.z`` -> ``bogie_bounce``: body kind and motion of a coordinate."""
    body, coordinate = dof_name.split(".")
    kind = "carbody" if body == "carbody" else body.split("_")[0]
    return f"{kind}_{_COORDINATE_MEANING[coordinate]}"
