"""The slowest speed the rig's fixed time step can simulate: a limit of the explicit step.

The wheel–rail creep forces (:mod:`susp_bo.rig.contact`) act on a wheelset like a damper
of rate ``2 f22 / V`` laterally and ``2 f11 b² / V`` in yaw (N·s/m, N·m·s/rad): as the
speed ``V`` falls they grow without bound. The forces are computed from the state at the
start of each PyBullet step and held over it (an explicit scheme), so a damping rate
``c/m`` with ``h c / m > 2`` makes the step amplify what it should damp: the run
diverges in a few steps, and where PyBullet's clamp on joint velocities stops it from
reaching the divergence limit the run returns meaningless signals instead.

:func:`step_is_stable` decides it exactly for the linear part of the model: it builds
the step's amplification matrix from the linearised rig (:func:`~susp_bo.rig.state_space.
state_space`: ``v⁺ = v + h a_v(z)``, ``q⁺ = q + h v⁺``, strokes explicit Euler, as
:func:`~susp_bo.rig.simulator.integrate` does) and looks for an eigenvalue outside the
unit circle on the negative real side: a mode the step flips and amplifies, which no
physical instability (hunting, whose eigenvalues lie near +1) produces. For the
``hst_trailer`` rig the minimum is 3.9 m/s at a 1 ms step, 7.9 m/s at 2 ms and 25.0 m/s
at 5 ms (measured: 3.8/3.9, 7.8/8.0 and 24.5/25 m/s diverge/run), and no speed up to
200 m/s runs at 10 ms. The limit scales about with the step: a smaller
``[simulation] time_step_s`` lowers it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from susp_bo.rig.spec_entries import SIMULATION_LIMITS

if TYPE_CHECKING:
    from susp_bo.rig.assembly import Assembly
    from susp_bo.rig.spec import RigSpec

__all__ = ["minimum_speed_m_s", "speed_problem", "step_is_stable"]

_GROWTH_TOLERANCE = 1e-9
"""|eigenvalue| above 1 + this counts as growing (round-off stays far below)."""

_RESOLUTION_M_S = 0.01
"""The minimum speed is found to this resolution (m/s) and reported rounded up to it."""


def step_is_stable(assembly: Assembly, speed_m_s: float, time_step_s: float) -> bool:
    """Whether the explicit step of ``time_step_s`` (s) is stable at ``speed_m_s`` (m/s).

    Args:
        assembly: the vehicle (:func:`~susp_bo.rig.assembly.build_assembly`).
        speed_m_s: train speed (m/s), > 0.
        time_step_s: the PyBullet step h (s), > 0.

    Returns:
        False where the step's amplification matrix has an eigenvalue ``μ`` with
        ``|μ| > 1`` and ``Re μ < 0`` (a mode the step itself makes grow).
    """
    from susp_bo.rig.state_space import state_space

    a = state_space(assembly, speed_m_s).a
    n, h = assembly.n_dofs, time_step_s
    step = np.eye(a.shape[0]) + h * a
    step[:n] += h * h * a[n : 2 * n]  # q⁺ = q + h v⁺ with v⁺ = v + h a_v(z)
    mu = np.linalg.eigvals(step)
    return not bool(np.any((np.abs(mu) > 1.0 + _GROWTH_TOLERANCE) & (mu.real < 0.0)))


def minimum_speed_m_s(assembly: Assembly, time_step_s: float) -> float:
    """The slowest speed (m/s) at which the step of ``time_step_s`` (s) is stable.

    Found by bisection on (0, the highest allowed speed], rounded up to 0.01 m/s;
    ``math.inf`` when even the highest allowed speed (200 m/s) is unstable (the step is
    too long for the rig at any speed).
    """
    high = SIMULATION_LIMITS["speed_m_s"][1]
    if not step_is_stable(assembly, high, time_step_s):
        return math.inf
    low = 0.0
    while high - low > 0.01 * _RESOLUTION_M_S:
        middle = 0.5 * (low + high)
        if step_is_stable(assembly, middle, time_step_s):
            high = middle
        else:
            low = middle
    return math.ceil(high / _RESOLUTION_M_S) * _RESOLUTION_M_S


def speed_problem(
    spec: RigSpec,
    speed_m_s: float,
    assembly: Assembly | None = None,
    speed_label: str = "speed",
) -> str | None:
    """Why ``spec`` cannot be simulated at ``speed_m_s`` (m/s) with its time step, or None.

    Args:
        spec: the rig (its parameters and ``[simulation] time_step_s``).
        speed_m_s: the slowest speed of the run (m/s).
        assembly: ``build_assembly(spec)`` when the caller has it.
        speed_label: what gave the speed, for the message (``--speed``,
            ``[simulation] speed_m_s``, a run's file).

    Returns:
        None when the step is stable; else e.g. ``"--speed: 20 m/s is not allowed: below
        the minimum speed 24.99 m/s of rig 'x' with [simulation] time_step_s = 0.005 s
        (…); give a speed of at least 24.99 m/s, or a smaller [simulation] time_step_s
        (the minimum falls about in proportion)"``, or, where no speed is stable,
        ``"[simulation] time_step_s: 0.01 s is too long for rig 'x' at any speed …"``.
    """
    from susp_bo.rig.assembly import build_assembly

    assembly = build_assembly(spec) if assembly is None else assembly
    step = spec.simulation.time_step_s
    if step_is_stable(assembly, speed_m_s, step):
        return None
    minimum = minimum_speed_m_s(assembly, step)
    if math.isinf(minimum):
        return (
            f"[simulation] time_step_s: {step:g} s is too long for rig {spec.name!r} at any "
            f"speed up to {SIMULATION_LIMITS['speed_m_s'][1]:g} m/s (the explicit step "
            "would diverge); give a smaller time_step_s, e.g. 0.002 s"
        )
    return (
        f"{speed_label}: {speed_m_s:g} m/s is not allowed: below the minimum speed "
        f"{minimum:.2f} m/s of rig {spec.name!r} with [simulation] time_step_s = {step:g} s "
        "(the wheel–rail creep damping grows as 1/speed and the explicit step would "
        f"diverge); give a speed of at least {minimum:.2f} m/s, or a smaller time_step_s "
        "(the minimum falls about in proportion)"
    )
