"""Steady curving on the moving frame: what a track design does to the vehicle.

On tangent track every body's coordinates are measured from one frame moving
with the train. On a designed line each body gets its own *reference frame*,
the pose it would take if it followed its supports rigidly: a wheelset the track
frame at its own chainage (centre line, heading, cant, height), a bogie frame
the chord through its two wheelset frames, the carbody the chord through the
two bogie frames (each chord rolled and raised by the mean of its ends). The
generalised coordinates ``q`` are the deviations from these references, so
they stay small in curves (a carbody sits ~``κ a²/2`` inside the centre line at
its own chainage, 0.26 m for R = 150 m; its deviation from the chord is mm).

Everything is written in the *car frame*: the track frame at the carbody
centre's chainage ``s_c`` (tangent, rolled by the cant ``θ_c`` there), moving
along the design with the train. Per time step (small angles in the frame):

* **offsets** ``d`` (n) and ``x_d`` (n_in): the reference poses in the car
  frame. Every suspension element sees ``u = G (q + d) + H (x + x_d)`` — its
  deflection includes the difference of its ends' references (chord versines,
  relative yaw of bogie and carbody, cant twist in transitions); damper rates
  include ``ḋ``. The flange sees the wheelset's offset from its own track
  frame (``x_d`` alignment equals the wheelset's ``d`` lateral). The creep
  forces are written in each wheelset's track frame, on ``q`` itself.
* **loads** (n): the frame's inertial and gravity terms on each body,
  ``−m (V² κ(s_B) cos θ_c + g sin θ_c)`` laterally and
  ``−m (g (cos θ_c cos α_c − 1) − V² κ(s_B) sin θ_c + V² G'(s_B))``
  vertically (α the gradient angle, G' the vertical curvature), and on every
  wheelset the yaw moment of the curving longitudinal creep
  ``−2 f11 b² κ(s_w)`` (outer wheel needing a larger rolling radius): with the
  conicity moment ``−2 f11 b λ y / r0`` its pure-rolling balance is
  ``y = −r0 b κ / λ`` (outwards).
* **sensor terms** (C): the quasi-static specific force in the body frame, on
  top of ``q̈`` and the gravity pick-up ``g · roll`` of the sensor rows:
  lateral ``V² κ(s_i) cos θ_c + g sin θ_c + g Δθ_B`` (``Δθ_B`` the body's
  reference roll relative to the car frame), vertical as the vertical load.

Neglected (documented): the frame's yaw and roll accelerations
(``I_z V² κ'`` ≈ 20 N·m in a 100 m transition to R = 5 km: negligible), the
second time derivative of the offsets (zero on linear ramps), Coriolis terms
(``2 V κ ẏ``), gravitational stiffness, the longitudinal gravity component of
the gradient (no longitudinal coordinate) and the pick-up of the lateral
specific force by a vertical sensor through body roll.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.assembly import GRAVITY_M_S2, Assembly
from susp_bo.rig.builder import Body
from susp_bo.rig.design import TrackDesign
from susp_bo.rig.elements import ElementGroup
from susp_bo.rig.spec import SensorSpec
from susp_bo.rig.track import SpeedProfile

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DesignInputs:
    """Design terms of one run at the step times (T of them).

    Attributes:
        offsets: ``[d, x_d]`` (T x (n + n_in)): reference poses in the car frame.
        rates: their time derivatives (T x (n + n_in)).
        loads: generalised inertial / gravity / creep loads (T x n).
        sensors: quasi-static specific force at every sensor (T x C) m/s².
    """

    offsets: FloatArray
    rates: FloatArray
    loads: FloatArray
    sensors: FloatArray


def _bogie_of(assembly: Assembly) -> dict[str, list[int]]:
    """Rigid non-carbody bodies (bogies) -> indices of the wheelsets they carry (nearest x)."""
    bogies = [b for b in assembly.bodies if b.kind == "rigid" and b.name != "carbody"]
    wheelsets = [b for b in assembly.bodies if b.kind == "wheelset"]
    carried: dict[str, list[int]] = {b.name: [] for b in bogies}
    if not bogies:
        return carried
    for index, wheelset in enumerate(wheelsets):
        nearest = min(bogies, key=lambda b: abs(b.cg_m[0] - wheelset.cg_m[0]))
        carried[nearest.name].append(index)
    return carried


def _chord(x: FloatArray, values: FloatArray, at: float) -> tuple[FloatArray, FloatArray]:
    """Value at ``at`` and slope of the straight line through (x_k, values_k) (k = 1 or 2).

    Args:
        x: positions (k,) m.
        values: (k x T) values at those positions.
        at: where to evaluate (m).
    """
    if len(x) == 1:
        return values[0], np.zeros_like(values[0])
    slope = (values[0] - values[-1]) / (x[0] - x[-1])
    return values[-1] + slope * (at - x[-1]), slope


def design_inputs(
    assembly: Assembly,
    design: TrackDesign,
    car_chainage_m: FloatArray,
    speed_m_s: FloatArray,
    time_step_s: float,
    sensors: Sequence[SensorSpec] = (),
) -> DesignInputs:
    """The design terms of a run (see the module docstring).

    Args:
        assembly: the vehicle.
        design: the line; must cover every body's chainage (checked by the caller).
        car_chainage_m: chainage of the car-frame origin (x = 0) at the step times (T,) m.
        speed_m_s: speed at the step times (T,) m/s.
        time_step_s: spacing of the step times (s), for the rates.
        sensors: the rig's sensor specs (``body``, ``position_m``, ``direction``), in
            channel order.
    """
    s_c = np.asarray(car_chainage_m, dtype=np.float64)
    v2 = np.asarray(speed_m_s, dtype=np.float64) ** 2
    n, n_in = assembly.n_dofs, assembly.n_inputs
    T = s_c.size
    offsets = np.zeros((T, n + n_in))
    loads = np.zeros((T, n))
    heading_c = design.heading_rad(s_c)
    lateral_c = design.lateral_m(s_c)
    height_c = design.height_m(s_c)
    grade_c = design.grade(s_c)[0]
    theta_c = design.roll_rad(s_c)
    cos_c, sin_c = np.cos(theta_c), np.sin(theta_c)

    def frame(x: float) -> dict[str, FloatArray]:
        """Track frame at car-frame position x, relative to the car frame (T,) each."""
        s = s_c + x
        return {
            "y": design.lateral_m(s) - lateral_c - heading_c * x,
            "yaw": design.heading_rad(s) - heading_c,
            "z": design.height_m(s) - height_c - grade_c * x,
            "roll": design.roll_rad(s) - theta_c,
        }

    def lateral_load(mass: float, x: float) -> FloatArray:
        return -mass * (v2 * design.curvature(s_c + x) * cos_c + GRAVITY_M_S2 * sin_c)

    def vertical_load(mass: float, x: float) -> FloatArray:
        s = s_c + x
        return -mass * (
            GRAVITY_M_S2 * (cos_c * np.cos(np.arctan(grade_c)) - 1.0)
            - v2 * design.curvature(s) * sin_c
            + v2 * design.grade(s)[1]
        )

    contact = assembly.contact
    wheelsets = [b for b in assembly.bodies if b.kind == "wheelset"]
    wheel_frames = []
    for a, body in enumerate(wheelsets):
        x = float(body.cg_m[0])
        f = frame(x)
        wheel_frames.append((x, f))
        y_ref = f["y"] - contact.rolling_radius * f["roll"]
        dof_y, dof_yaw = body.dofs
        offsets[:, dof_y] = y_ref
        offsets[:, dof_yaw] = f["yaw"]
        offsets[:, n + 3 * a] = f["z"]
        offsets[:, n + 3 * a + 1] = f["roll"]
        offsets[:, n + 3 * a + 2] = y_ref  # the flange sees the wheelset's own track frame
        loads[:, dof_y] = lateral_load(body.mass, x)
        loads[:, dof_yaw] = (
            -2.0
            * contact.longitudinal_creep
            * contact.half_contact_spacing**2
            * design.curvature(s_c + x)
        )
    references: dict[str, dict[str, FloatArray]] = {}

    def place(body: Body, ref: dict[str, FloatArray]) -> None:
        y, z, roll, pitch, yaw = body.dofs
        height = body.cg_m[2]
        offsets[:, y] = ref["y"] - height * ref["roll"]  # rolled about the rail-level axis
        offsets[:, z] = ref["z"]
        offsets[:, roll] = ref["roll"]
        offsets[:, pitch] = -ref["z_slope"]
        offsets[:, yaw] = ref["y_slope"]
        x = float(body.cg_m[0])
        loads[:, y] = lateral_load(body.mass, x)
        loads[:, z] = vertical_load(body.mass, x)
        references[body.name] = ref

    def chord_reference(points: list[tuple[float, dict[str, FloatArray]]], at: float) -> dict:
        xs = np.array([p[0] for p in points])
        ref: dict[str, FloatArray] = {}
        for key in ("y", "z", "roll"):
            value, slope = _chord(xs, np.array([p[1][key] for p in points]), at)
            ref[key] = value
            ref[f"{key}_slope"] = slope
        return ref

    bogie_points = []
    for name, carried in _bogie_of(assembly).items():
        body = assembly.body(name)
        if not carried:
            continue
        ref = chord_reference([wheel_frames[a] for a in carried], float(body.cg_m[0]))
        place(body, ref)
        bogie_points.append((float(body.cg_m[0]), ref))
    carbody = next((b for b in assembly.bodies if b.name == "carbody"), None)
    if carbody is not None and bogie_points:
        place(carbody, chord_reference(bogie_points, float(carbody.cg_m[0])))
    rates = np.gradient(offsets, time_step_s, axis=0) if T > 1 else np.zeros_like(offsets)
    sensor_terms = np.zeros((T, len(sensors)))
    for c, sensor in enumerate(sensors):
        x = float(sensor.position_m[0])
        roll = references.get(sensor.body, {}).get("roll", 0.0)
        if sensor.direction == "lateral":
            sensor_terms[:, c] = v2 * design.curvature(s_c + x) * cos_c + GRAVITY_M_S2 * (
                sin_c + roll
            )
        else:
            sensor_terms[:, c] = -vertical_load(1.0, x)
    return DesignInputs(offsets, rates, loads, sensor_terms)


def steady_state(
    assembly: Assembly,
    offsets: FloatArray,
    loads: FloatArray,
    max_iterations: int = 60,
) -> tuple[FloatArray, FloatArray]:
    """Quasi-static equilibrium ``q`` (n,) under design offsets and loads, dead bands nonlinear.

    Solves ``Q(q) = 0`` with zero velocities by Newton's method: springs,
    dead bands (bump stops, flange — their full smoothed law) and the creep
    stiffness; series (yaw) dampers carry no force in a steady state (their
    stroke follows the deflection) and dampers none at rest.

    Args:
        assembly: the vehicle.
        offsets: ``[d, x_d]`` (n + n_in,) at the instant, or (T x (n + n_in)) for T
            instants solved together.
        loads: generalised loads (n,) at the instant, or (T x n).

    Returns:
        ``(q, u_dead)``: the equilibrium (n,) or (T x n) and the dead-band
        deflections there (m_dead,) or (T x m_dead), from which flange or
        bump-stop contact is read.

    Raises:
        RuntimeError: Newton's method did not converge.
    """
    from susp_bo.rig.elements import dead_band_force

    single = np.ndim(offsets) == 1
    offsets = np.atleast_2d(np.asarray(offsets, dtype=np.float64))
    loads = np.atleast_2d(np.asarray(loads, dtype=np.float64))
    n, n_in = assembly.n_dofs, assembly.n_inputs
    springs, dead = assembly.springs, assembly.dead_bands

    def rows(group: ElementGroup) -> FloatArray:
        return np.hstack([group.coordinates, group.inputs])

    gs, gd = rows(springs.group), rows(dead.group)
    creep = assembly.contact.matrices(n, n_in, 1.0)["stiffness"]
    k_springs = gs[:, :n].T @ (springs.stiffness[:, None] * gs[:, :n])
    q = np.zeros((offsets.shape[0], n))
    for _ in range(max_iterations):
        z = np.hstack([q, np.zeros((q.shape[0], n_in))]) + offsets
        u_s = z @ gs.T
        u_d = z @ gd.T
        f_d = dead_band_force(u_d, dead.stiffness, dead.gap, dead.smoothing)
        residual = loads - (springs.stiffness * u_s) @ gs[:, :n] - f_d @ gd[:, :n] - q @ creep.T
        with np.errstate(over="ignore"):
            a_plus = 1.0 / (1.0 + np.exp(-(u_d - dead.gap) / dead.smoothing))
            a_minus = 1.0 / (1.0 + np.exp(-(-u_d - dead.gap) / dead.smoothing))
        slope = dead.stiffness * (a_plus + a_minus)  # (T x m_dead)
        jacobian = (
            k_springs[None] + np.einsum("mi,tm,mj->tij", gd[:, :n], slope, gd[:, :n]) + creep[None]
        )
        step = np.linalg.solve(jacobian, residual[:, :, None])[:, :, 0]
        q = q + step
        if np.max(np.abs(step)) < 1e-12:
            z = np.hstack([q, np.zeros((q.shape[0], n_in))]) + offsets
            u_d = z @ gd.T
            return (q[0], u_d[0]) if single else (q, u_d)
    raise RuntimeError(f"steady_state: Newton did not converge in {max_iterations} iterations")


def reference_specific_force(
    assembly: Assembly,
    sensors: Sequence[SensorSpec],
    design: TrackDesign,
    speed: SpeedProfile,
    time_s: FloatArray,
) -> FloatArray:
    """Specific force each sensor reads on a vehicle riding its reference frames, (C x n_t).

    This is the design's quasi-static part of the signals — ``V² κ(s_i) + g sin θ``
    with the roll of the sensor's body reference (chord of its supports), see the
    module docstring — and what the spectra remove on a designed line. It depends
    on the design, the speed record and the vehicle's geometry (axle, bogie and
    sensor positions) only, never on suspension parameters, so measured and
    simulated signals get exactly the same treatment. What remains is the
    vehicle's own response: dynamics plus its quasi-static roll-out and offsets.

    Args:
        assembly: the vehicle (geometry).
        sensors: sensor specs in channel order (C,).
        design: the line.
        speed: the :class:`~susp_bo.rig.track.SpeedProfile` of the run.
        time_s: sample times on the speed clock (n_t,) s; the rearmost axle is at
            chainage 0 at t = 0 (the measured-run convention).
    """
    times = np.asarray(time_s, dtype=np.float64)
    car = -float(np.min(assembly.axle_positions_m)) + speed.distance_m(times)
    velocity = speed.speed_at(times)
    return design_inputs(assembly, design, car, velocity, 1.0, sensors).sensors.T
