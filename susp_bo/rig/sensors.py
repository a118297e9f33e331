"""Accelerometers: specific force along body axes at named points, sampled like real sensors.

A sensor on a rigid body at point ``r`` (from the centre of gravity) measuring
along body axis ``e`` reads the specific force ``e · Rᵀ (a_P - g)`` minus the
static gravity: with small rotations, vertical ``a_z + α_x r_y - α_y r_x`` and
lateral ``a_y + α_z r_x - α_x r_z + g φ`` (gravity picked up through roll φ).
The rows on ``q̈`` and ``q`` are assembled in assembly.py.

Sampling: each output sample is the mean acceleration over one sample interval
``T = 1 / sample_rate`` (the velocity change over T divided by T: an ideal
anti-alias boxcar), with the gravity term averaged over its end points; the
sample time is the interval centre.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from susp_bo.numerics import one_blas_thread
from susp_bo.rig.assembly import Assembly

FloatArray = NDArray[np.float64]


def sample_sensors(
    assembly: Assembly, q: FloatArray, qdot: FloatArray, steps_per_sample: int, time_step_s: float
) -> tuple[FloatArray, FloatArray]:
    """Sensor signals from coordinates and velocities at the step times.

    Args:
        assembly: the vehicle (sensor rows).
        q: coordinates at step times 0, dt, 2dt, …, (n_steps x n) or every
            ``steps_per_sample``-th step when already decimated (see ``decimated``).
        qdot: velocities, same shape.
        steps_per_sample: steps per output sample.
        time_step_s: the step dt (s).

    Returns:
        ``(time_s (n_samples,), signals (C x n_samples) m/s²)``, times relative to
        the first row of ``q``.
    """
    return sample_decimated(
        assembly, q[::steps_per_sample], qdot[::steps_per_sample], steps_per_sample * time_step_s
    )


def sample_decimated(
    assembly: Assembly, q: FloatArray, qdot: FloatArray, sample_interval_s: float
) -> tuple[FloatArray, FloatArray]:
    """Sensor signals from states taken every ``sample_interval_s`` (s), (n_k x n) each.

    The products run on one BLAS thread: with two, 7 of 30 000 values of the demo's
    synthesised run changed in their last bit (:func:`susp_bo.numerics.one_blas_thread`).
    """
    with one_blas_thread():
        velocity = qdot @ assembly.sensor_acceleration.T  # (n_k x C) sensor-point velocities
        position = q @ assembly.sensor_displacement.T
    acceleration = np.diff(velocity, axis=0) / sample_interval_s
    pickup = 0.5 * (position[1:] + position[:-1])
    time = (np.arange(acceleration.shape[0]) + 0.5) * sample_interval_s
    return time, np.ascontiguousarray((acceleration + pickup).T)
