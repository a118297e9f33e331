"""Rig speed: simulated seconds per wall second, ratio to bare PyBullet stepping, profile.

Run on one core (BLAS threads pinned to 1 before numpy loads)::

    python benchmarks/rig_speed.py            # 60 s of simulated track
    python benchmarks/rig_speed.py --quick    # 20 s, for a smoke check
    python benchmarks/rig_speed.py --line FILE  # the curved-line figures on a line file

Prints, all measured in this run:

* the full reference car (hst_trailer, every sensor, nonlinear elements) at the
  rig's time step: simulated s per wall s (× real time);
* bare PyBullet stepping of the same multibody (no state reads, no forces) and the
  ratio of the two;
* where the time per step goes (state read, force model, torque write, step);
* the time-step check: spectra at dt and dt/2 on the same track (dB deviation);
* PyBullet (linear elements) vs the linearised model on the same track (dB);
* the linearised model: time per expected spectrum and per time response;
* a curved line (built-in S-curve R = 7000 m, 150 mm cant, with transitions, or
  ``--line FILE``): wall time of the same run on it, ratio to bare stepping and
  to tangent track, and the linearised model on it (operating points along the line).
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
from operator import itemgetter  # noqa: E402

import numpy as np  # noqa: E402
import pybullet  # noqa: E402

from susp_bo.rig.assembly import build_assembly  # noqa: E402
from susp_bo.rig.dynamics import ForceModel  # noqa: E402
from susp_bo.rig.line_file import design_from_segments, load_line  # noqa: E402
from susp_bo.rig.linear import LinearisedRig  # noqa: E402
from susp_bo.rig.simulator import Rig, excitation_for_run, synthetic_track  # noqa: E402
from susp_bo.rig.spec import load_rig_spec  # noqa: E402
from susp_bo.rig.world import VehicleWorld  # noqa: E402

DB = 20.0 / math.log(10.0)


def profile_steps(spec, track, steps: int) -> dict[str, float]:
    """Mean µs per step of each part of the integration loop (instrumented copy)."""
    assembly = build_assembly(spec)
    sim = spec.simulation
    excitation, _ = excitation_for_run(
        assembly,
        track,
        sim.speed_m_s,
        steps * sim.time_step_s,
        sim.time_step_s,
        sim.sample_rate_hz,
    )
    world = VehicleWorld(sim.time_step_s)
    world.build(assembly)
    forces = ForceModel(assembly)
    x_all = np.zeros((excitation.time_s.size, assembly.n_inputs))
    for c, name in enumerate(("vertical_m", "cross_level_rad", "alignment_m")):
        x_all[:, c::3] = getattr(excitation, name).T
    client, body, joints = world.client._client, world.body_id, world.joints
    stroke = np.zeros(forces.n_strokes)
    position_of, velocity_of, n_joints = itemgetter(0), itemgetter(1), len(joints)
    totals = dict.fromkeys(("read", "forces", "write", "step"), 0.0)
    clock = time.perf_counter
    n = min(steps, excitation.time_s.size - 1)
    for j in range(n):
        t0 = clock()
        states = pybullet.getJointStates(body, joints, physicsClientId=client)
        q = np.fromiter(map(position_of, states), np.float64, n_joints)  # as in integrate
        qd = np.fromiter(map(velocity_of, states), np.float64, n_joints)
        t1 = clock()
        generalised, rate = forces(q, qd, x_all[j], x_all[j], sim.speed_m_s, stroke)
        stroke += sim.time_step_s * rate
        t2 = clock()
        pybullet.setJointMotorControlArray(
            body,
            joints,
            pybullet.TORQUE_CONTROL,
            forces=generalised.tolist(),
            physicsClientId=client,
        )
        t3 = clock()
        pybullet.stepSimulation(physicsClientId=client)
        t4 = clock()
        totals["read"] += t1 - t0
        totals["forces"] += t2 - t1
        totals["write"] += t3 - t2
        totals["step"] += t4 - t3
    world.close()
    return {k: 1e6 * v / n for k, v in totals.items()}


def bare_stepping(spec, steps: int) -> float:
    """Wall seconds for ``steps`` bare stepSimulation calls of the same multibody."""
    world = VehicleWorld(spec.simulation.time_step_s)
    world.build(build_assembly(spec))
    client = world.client._client
    start = time.perf_counter()
    for _ in range(steps):
        pybullet.stepSimulation(physicsClientId=client)
    elapsed = time.perf_counter() - start
    world.close()
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="20 s of track instead of 60 s")
    parser.add_argument("--rig", default="hst_trailer")
    parser.add_argument("--line", help="line design file for the curved-line figures")
    args = parser.parse_args()
    duration = 20.0 if args.quick else 60.0
    spec = load_rig_spec(args.rig).with_simulation(duration_s=duration)
    sim = spec.simulation
    track = synthetic_track(spec, seed=1)
    simulated_s = sim.warm_up_s + duration
    steps = round(simulated_s / sim.time_step_s)
    print(
        f"rig {spec.name}: {build_assembly(spec).n_dofs} coordinates, "
        f"{len(spec.channels)} sensors, dt = {1e3 * sim.time_step_s:g} ms, "
        f"V = {sim.speed_m_s} m/s, {simulated_s:g} s simulated ({steps} steps)"
    )

    with Rig(spec) as rig:
        start = time.perf_counter()
        response = rig.simulate(track)
        full = time.perf_counter() - start
    bare = bare_stepping(spec, steps)
    print(
        f"full rig:      {full:7.3f} s wall, {simulated_s / full:7.1f} x real time, "
        f"{1e6 * full / steps:6.1f} µs/step"
    )
    print(
        f"bare stepping: {bare:7.3f} s wall, {simulated_s / bare:7.1f} x real time, "
        f"{1e6 * bare / steps:6.1f} µs/step"
    )
    print(f"ratio full / bare stepping: {full / bare:.2f}")

    parts = profile_steps(spec, track, min(steps, 5000))
    total = sum(parts.values())
    print("profile per step (instrumented loop):")
    for name, micro in parts.items():
        print(f"  {name:7s} {micro:6.1f} µs  {100 * micro / total:5.1f} %")

    with Rig(spec.with_simulation(time_step_s=sim.time_step_s / 2)) as fine_rig:
        fine = fine_rig.simulate(track)
    halving = DB * np.abs(fine.spectra().log_amplitude - response.spectra().log_amplitude)
    print(
        f"time step halved ({1e3 * sim.time_step_s:g} -> {0.5e3 * sim.time_step_s:g} ms): "
        f"median {np.median(halving):.3f} dB, 95th pct {np.percentile(halving, 95):.3f} dB, "
        f"max {halving.max():.3f} dB"
    )

    linear = LinearisedRig(spec)
    with Rig(spec, linear_elements=True) as linear_rig:
        simulated = linear_rig.simulate(track)
    start = time.perf_counter()
    reference = linear.response(track, sim.speed_m_s)
    response_time = time.perf_counter() - start
    deviation = DB * np.abs(simulated.spectra().log_amplitude - reference.spectra().log_amplitude)
    print(
        f"PyBullet (linear elements) vs linearised model, same track: median "
        f"{np.median(deviation):.3f} dB, 95th pct {np.percentile(deviation, 95):.3f} dB, "
        f"max {deviation.max():.3f} dB"
    )
    start = time.perf_counter()
    repeats = 5
    for _ in range(repeats):
        linear.spectra()
    per_spectrum = (time.perf_counter() - start) / repeats
    print(
        f"linearised model: {1e3 * per_spectrum:.1f} ms per expected spectrum (all channels), "
        f"{response_time:.2f} s per {simulated_s:g} s time response; "
        f"{full / per_spectrum:.0f}x faster than one PyBullet run"
    )
    curved_line(spec, track, args.line)


S_CURVE = [
    {"type": "tangent", "length_m": 400.0},
    {"type": "transition", "length_m": 250.0},
    {
        "type": "curve",
        "length_m": 1200.0,
        "radius_m": 7000.0,
        "cant_mm": 150.0,
        "direction": "left",
    },
    {"type": "transition", "length_m": 250.0},
    {
        "type": "curve",
        "length_m": 6000.0,
        "radius_m": 7000.0,
        "cant_mm": 150.0,
        "direction": "right",
    },
]


def curved_line(spec, track, line: str | None) -> None:
    """The same run on a curved line: cost ratios and the linearised model on it."""
    design = load_line(line) if line else design_from_segments(S_CURVE, source="built-in S-curve")
    walls: dict[str, list[float]] = {"curved": [], "tangent": []}
    with Rig(spec) as rig:  # alternate, best of 3 each: the machine is shared
        for _ in range(3):
            start = time.perf_counter()
            curved = rig.simulate(track, design=design)
            walls["curved"].append(time.perf_counter() - start)
            start = time.perf_counter()
            tangent = rig.simulate(track)
            walls["tangent"].append(time.perf_counter() - start)
    wall, flat = min(walls["curved"]), min(walls["tangent"])
    steps = round(
        (spec.simulation.warm_up_s + spec.simulation.duration_s) / spec.simulation.time_step_s
    )
    bare = min(bare_stepping(spec, steps) for _ in range(3))
    difference = DB * np.abs(curved.spectra().log_amplitude - tangent.spectra().log_amplitude)
    print(
        f"curved line ({design.source}), best of 3: {wall:7.3f} s wall; ratio to bare stepping "
        f"{wall / bare:.2f} (tangent {flat / bare:.2f}), to tangent track {wall / flat:.2f}; "
        f"spectra vs tangent (quasi-static part removed): median {np.median(difference):.3f} "
        f"dB, max {difference.max():.3f} dB"
    )
    linear = LinearisedRig(spec)
    start = time.perf_counter()
    points = linear.operating_points(design)
    spectra = linear.spectra(design=design)
    per_line = time.perf_counter() - start
    start = time.perf_counter()
    flat = linear.spectra()
    per_tangent = time.perf_counter() - start
    shift = DB * np.abs(spectra.log_amplitude - flat.log_amplitude)
    print(
        f"linearised model on the line: {len(points)} operating points, "
        f"{1e3 * per_line:.0f} ms per expected spectrum ({per_line / per_tangent:.1f}x tangent); "
        f"shift vs tangent max {shift.max():.3f} dB"
    )


if __name__ == "__main__":
    main()
