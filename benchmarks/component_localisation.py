"""Which single-component failures can the shipped sensors localise? (issue 13)

Part 1 (always, about 3 s): on the linearised hst_trailer (expected spectra on the rig's
random track, 300 km/h), every yaw damper, secondary vertical damper side and primary
vertical damper (axlebox) at ``--fraction`` of its nominal damping, one at a time
(per-component parameters ``<parameter>@<component>``). Prints each failure's rms
spectral change per channel and its detection z, and for chosen pairs the angle between
their signatures and z over all channels, the carbody and the bogie-frame channels
(:mod:`susp_bo.rig.localisation`) — twice: with the scatter of an unknown track (σ =
1.5 dB) and with the paired error model's σ per band (track measured, sensor noise
``--noise`` m/s², one record of the rig's length, Welch noise model).

``--pybullet`` adds the yaw and secondary vertical dampers on PyBullet (one 30 s record on
one seeded track, about 20 s).

Part 2 (``--calibrate``): a q = 2 calibration of two per-component parameters
(``--pair``, default: left and right yaw damper of the front bogie), the first worn to
``--worn`` of nominal, with the real loop (:func:`susp_bo.calibration.loop.calibrate`)
on the fast path of ``benchmarks/fast_path.py`` (linearised rig, ν seeded German-PSD
tracks, white noise ``--noise`` m/s², ``--error`` paired or unpaired, demo settings,
budget ``--budget``), and the exact-likelihood posterior on a ``--grid`` x ``--grid``
grid (uniform prior on C_w, zoomed twice onto the 12-nat region; no surrogate) as the
reference.

Measured (issue 13 session, 2 shared cores, OMP_NUM_THREADS=1)::

    python benchmarks/component_localisation.py

rms change (dB, 0.3–20 Hz) at 50 %: a yaw damper ≤ 0.14 dB in every channel (bogie
lateral of its own bogie 0.14 front / 0.11 rear, carbody lateral 0.07–0.11): detection
z 1.0–1.2 at 1.5 dB, 47–55 paired. Secondary vertical damper: carbody vertical up to
1.7 dB, bogie vertical of its bogie 1.24–1.29 dB on the sensor's (left) side, 0.16–0.17
on the other. Primary vertical damper: carbody vertical 2.0–2.5 dB at its end, bogie
vertical 0.31–0.59 dB (own bogie), nothing on the other bogie.

Pairs, z (all channels) unknown track / paired, noise 0.01; cos at 1.5 dB:

- left vs right of one bogie: carbody cos = 1.000 for every type (the carbody sensors
  sit on the centre line: mirror symmetry), only the left-side bogie sensors differ.
  Yaw 0.2 not localisable / 7.9 localisable (cos 0.988); secondary vertical 5.2 / 300
  (cos 0.865); primary vertical (wheelset 1) 3.6 weak / 458 (cos 0.959).
- front vs rear bogie: yaw 1.0 not localisable (not even detected) / 46; secondary
  vertical 11.8 / 1317; primary wheelset 1 vs 3 10.4 / 997; wheelset 1 vs 2 (one
  bogie) 8.8 / 579.

    python benchmarks/component_localisation.py --calibrate [--noise 0.05 | --error unpaired]
        [--pair A,B]   # A,B: yaw_damper_damping@bogie_front_left,…@bogie_rear_left or
                       # secondary_vertical_damping@bogie_front_left,…@bogie_front_right

    python benchmarks/component_localisation.py --pybullet

PyBullet, one track (seed 11): the same orders of magnitude (yaw dampers ≤ 0.17 dB,
detection z 1.0–1.4; secondary vertical 12.7–14.1), but left and right no longer look
the same from the carbody on one record (cos 0.58 yaw, 0.94 secondary vertical): one
track realisation is not mirror-symmetric — information for a paired calibration,
scatter for an unpaired one. At 1.5 dB: yaw FL/FR z 0.8 and FL/RL 0.9 (not localisable),
secondary vertical FL/FR 6.8 (localisable), FL/RL 12.6.

Exact grid posterior (mean ± sd, correlation; truth: first at 50 %, second nominal) and
the loop (60 evaluations, 9–15 s each; grid 87–144 s):

- yaw FL / FR, paired, noise 0.01: 2.41 ± 0.026 / 5.00 ± 0.087 MN·s/m (truth 2.45 /
  4.90), −0.66; loop 2.41 ± 0.026 / 5.00 ± 0.088, −0.66, intervals hold the truth,
  verdict trusted. Localised: the worn side is found.
- same, noise 0.05: 2.28 ± 0.12 / 5.54 ± 0.53, −0.64; loop the same within 2 %
  (not trusted). Localised, the healthy side wide.
- same, unpaired: 3.56 ± 1.56 / 4.91 ± 1.67, −0.40 (the uniform prior's sd: 2.17);
  loop 3.53 ± 1.47 / 4.83 ± 1.61 (not trusted). Neither detected nor localised.
- yaw FL / rear-left, unpaired: 3.30 ± 1.41 / 5.30 ± 1.48, −0.21; loop 3.33 ± 1.37 /
  5.22 ± 1.42 (not trusted: not_converged). Not detected.
- yaw FL / rear-left, paired, noise 0.01: 2.432 ± 0.021 / 4.903 ± 0.066, −0.34; loop
  the same, trusted. Localised.
- secondary vertical FL / FR, unpaired: 20.6 ± 1.2 / 39.5 ± 1.6 kN·s/m (truth 20 /
  40), −0.46; loop 20.6 ± 1.24 / 39.5 ± 1.61 (not trusted). Localised, as z = 5.2 said.

Weak: z assumes independent bands and an exact model; the paired posteriors would widen
with model error. The predicted correlation of the yaw pair (−cos θ = −0.99) is stronger
than the measured −0.66: the signatures are secants from the nominal car on expected
spectra, the calibration sees three specific tracks.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # small matrices: threads only contend (2 shared cores)

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from fast_path import FastPathProblem, Options, demo_settings  # noqa: E402

from susp_bo.calibration.loop import calibrate  # noqa: E402
from susp_bo.calibration.welch_noise import (  # noqa: E402
    band_relative_covariance,
    noise_residual_moments,
)
from susp_bo.rig.components import split_component_name  # noqa: E402
from susp_bo.rig.linear import LinearisedRig  # noqa: E402
from susp_bo.rig.localisation import (  # noqa: E402
    UNKNOWN_TRACK_SCATTER_DB,
    failure_signatures,
    format_separations,
    format_signatures,
    pair_separation,
    single_component_failures,
)
from susp_bo.rig.sensitivity import DB_PER_NEPER  # noqa: E402
from susp_bo.rig.simulator import Rig, synthetic_track  # noqa: E402
from susp_bo.rig.spec import CalibrationParameter, RigSpec, load_rig_spec  # noqa: E402
from susp_bo.rig.spectra import with_noise_floor  # noqa: E402

Y, S, P = "yaw_damper_damping@", "secondary_vertical_damping@", "primary_vertical_damping@"
PAIRS = (
    (Y + "bogie_front_left", Y + "bogie_front_right"),
    (Y + "bogie_front_left", Y + "bogie_rear_left"),
    (S + "bogie_front_left", S + "bogie_front_right"),
    (S + "bogie_front_left", S + "bogie_rear_left"),
    (P + "wheelset_1_left", P + "wheelset_1_right"),
    (P + "wheelset_1_left", P + "wheelset_2_left"),
    (P + "wheelset_1_left", P + "wheelset_3_left"),
)
"""Pairs of the study: left/right of one bogie, front/rear bogie, leading/trailing axle."""
CHANNEL_SETS = ("all", "carbody", "bogie")


def paired_scatter_db(spec: RigSpec, noise_m_s2: float) -> np.ndarray:
    """σ (C x F) dB of a paired residual: sensor noise on the nominal car's spectra.

    The Welch noise model of the ``paired`` error model
    (:func:`susp_bo.calibration.welch_noise.noise_residual_moments`) for one record of
    the rig's duration, with white noise of ``noise_m_s2`` m/s² rms.
    """
    sim = spec.simulation
    n_samples = round(sim.duration_s * sim.sample_rate_hz)
    relative = band_relative_covariance(spec.spectrum, n_samples, sim.sample_rate_hz)
    nominal = with_noise_floor(
        LinearisedRig(spec).spectra().log_amplitude, noise_m_s2, sim.sample_rate_hz
    )
    _, cov = noise_residual_moments(nominal, 2.0 * noise_m_s2**2 / sim.sample_rate_hz, relative)
    return DB_PER_NEPER * np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))


def tables(spec: RigSpec, fraction: float, noise_m_s2: float) -> str:
    """Part 1: the signature table and the pair tables (unknown / measured track)."""
    signatures = failure_signatures(
        LinearisedRig(spec).spectra, single_component_failures(spec, fraction=fraction)
    )
    paired = paired_scatter_db(spec, noise_m_s2)
    out = []
    for title, sigma in (
        (f"track unknown (unpaired): σ = {UNKNOWN_TRACK_SCATTER_DB} dB", UNKNOWN_TRACK_SCATTER_DB),
        (
            f"track measured (paired), sensor noise {noise_m_s2} m/s², one record: σ per band "
            f"{np.min(paired):.3g}–{np.max(paired):.3g} dB (median {np.median(paired):.3g})",
            paired,
        ),
    ):
        rows = [pair_separation(signatures, a, b, c, sigma) for a, b in PAIRS for c in CHANNEL_SETS]
        out += [title, format_signatures(signatures, sigma), format_separations(rows), ""]
    return "\n".join(out)


def pybullet_tables(spec: RigSpec, fraction: float, seed: int = 11) -> str:
    """The same on PyBullet, one track (``synthetic_track(spec, seed)``), σ = 1.5 dB."""
    failures = single_component_failures(
        spec, ("yaw_damper_damping", "secondary_vertical_damping"), fraction
    )
    track = synthetic_track(spec, seed=seed)
    with Rig(spec) as rig:
        signatures = failure_signatures(lambda p: rig.spectra(track, parameters=p), failures)
    rows = [pair_separation(signatures, a, b, c) for a, b in PAIRS[:4] for c in CHANNEL_SETS]
    title = f"PyBullet, one track (seed {seed}), σ = {UNKNOWN_TRACK_SCATTER_DB} dB"
    return "\n".join([title, format_signatures(signatures), format_separations(rows)])


def component_spec(spec: RigSpec, names: tuple[str, str]) -> RigSpec:
    """The rig with C_w = the two per-component parameters (the bounds of their type)."""
    entries = []
    for name in names:
        base, _ = split_component_name(name, spec.parameters)
        shared = next(c for c in spec.calibration if c.name == base)
        entries.append(
            CalibrationParameter(
                name, shared.lower, shared.upper, shared.reference, shared.unit, name
            )
        )
    return dataclasses.replace(spec, calibration=tuple(entries))


def calibration_study(
    spec: RigSpec, names: tuple[str, str], worn: float, args: argparse.Namespace
) -> str:
    """Part 2: the loop's posterior and the exact grid posterior, as text."""
    cal = component_spec(spec, names)
    truth = cal.calibration_reference * np.array([worn, 1.0])
    options = Options(
        nu=args.nu, noise=args.noise, seed=0, error=args.error, budget=args.budget,
        smoke=False, local_search=True,
    )  # fmt: skip
    problem = FastPathProblem(cal, dict(zip(names, truth.tolist())), options, seed=7)
    bounds = cal.calibration_bounds
    lines = [f"truth: {names[0]} = {truth[0]:.4g}, {names[1]} = {truth[1]:.4g} N·s/m"]
    started = time.perf_counter()
    # exact posterior on a grid (uniform prior on C_w): the reference, no surrogate;
    # zoomed twice onto the cells within 12 nats of the maximum (plus one cell around)
    box = bounds.copy()
    for _ in range(3):
        axes = [np.linspace(box[0, j], box[1, j], args.grid) for j in range(2)]
        log_l = np.array([[problem.log_l(np.array([a, b])) for b in axes[1]] for a in axes[0]])
        high = np.argwhere(log_l > np.nanmax(log_l) - 12.0)
        low = np.maximum(high.min(axis=0) - 1, 0)
        top = np.minimum(high.max(axis=0) + 1, args.grid - 1)
        box = np.array([[axes[j][low[j]] for j in range(2)], [axes[j][top[j]] for j in range(2)]])
    weight = np.exp(log_l - np.nanmax(log_l))
    weight /= np.nansum(weight)
    grid = np.stack(np.meshgrid(*axes, indexing="ij"))  # (2 x G x G)
    mean = np.array([np.nansum(weight * grid[j]) for j in range(2)])
    cov = np.array(
        [[np.nansum(weight * (grid[i] - mean[i]) * (grid[j] - mean[j])) for j in range(2)]
         for i in range(2)]
    )  # fmt: skip
    sd = np.sqrt(np.diag(cov))
    lines.append(
        f"exact grid {args.grid}x{args.grid} ({time.perf_counter() - started:.0f} s): "
        f"mean {mean[0]:.4g}, {mean[1]:.4g}; sd {sd[0]:.3g}, {sd[1]:.3g} "
        f"({100 * sd[0] / (bounds[1, 0] - bounds[0, 0]):.1f} %, "
        f"{100 * sd[1] / (bounds[1, 1] - bounds[0, 1]):.1f} % of C_w); "
        f"correlation {cov[0, 1] / (sd[0] * sd[1]):+.3f}; "
        f"sum mean {mean.sum():.4g} sd {np.sqrt(cov.sum()):.3g} (truth {truth.sum():.4g}); "
        f"final grid box [{axes[0][0]:.4g}, {axes[0][-1]:.4g}] x [{axes[1][0]:.4g}, "
        f"{axes[1][-1]:.4g}]; log L max {np.nanmax(log_l):.1f}, at truth "
        f"{problem.log_l(truth):.1f}"
    )
    if args.grid_only:
        return "\n".join(lines)
    settings = demo_settings(options, 0)
    started = time.perf_counter()
    result = calibrate(problem, bounds, names, settings, progress=False)
    draws = result.draws.reshape(-1, 2)
    c = np.corrcoef(draws.T)[0, 1]
    interval = np.asarray(result.summary.interval95)
    inside = (interval[:, 0] <= truth) & (truth <= interval[:, 1])
    verdict = None if result.reliability is None else result.reliability.verdict
    if result.reliability is not None and result.reliability.codes:
        verdict = f"{verdict} ({', '.join(result.reliability.codes)})"
    lines.append(
        f"loop ({result.n_evaluations} evaluations, {time.perf_counter() - started:.0f} s, "
        f"verdict {verdict}): mean {draws[:, 0].mean():.4g}, {draws[:, 1].mean():.4g}; "
        f"sd {draws[:, 0].std():.3g}, {draws[:, 1].std():.3g}; correlation {c:+.3f}; "
        f"95 % intervals [{interval[0, 0]:.3g}, {interval[0, 1]:.3g}], "
        f"[{interval[1, 0]:.3g}, {interval[1, 1]:.3g}] hold the truth: {inside.tolist()}"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Print the tables (and the q = 2 calibration with ``--calibrate``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rig", default="hst_trailer")
    parser.add_argument("--fraction", type=float, default=0.5, help="failed / nominal")
    parser.add_argument("--calibrate", action="store_true", help="run part 2")
    parser.add_argument("--pybullet", action="store_true", help="part 1 on PyBullet too")
    parser.add_argument(
        "--pair",
        default=f"{Y}bogie_front_left,{Y}bogie_front_right",
        help="the two per-component parameters of part 2 (the first is worn)",
    )
    parser.add_argument("--worn", type=float, default=0.5, help="worn / nominal (part 2)")
    parser.add_argument("--nu", type=int, default=3)
    parser.add_argument("--noise", type=float, default=0.01, help="m/s² white sensor noise")
    parser.add_argument("--error", choices=("paired", "unpaired"), default="paired")
    parser.add_argument("--budget", type=int, default=60)
    parser.add_argument("--grid", type=int, default=31)
    parser.add_argument("--grid-only", action="store_true", help="part 2 without the loop")
    args = parser.parse_args(argv)
    spec = load_rig_spec(args.rig)
    print(tables(spec, args.fraction, args.noise))
    if args.pybullet:
        print(pybullet_tables(spec, args.fraction))
    if args.calibrate:
        names = tuple(n.strip() for n in args.pair.split(","))
        if len(names) != 2:
            parser.error(f"--pair: got {args.pair!r}; expected two names a,b")
        print()
        print(calibration_study(spec, (names[0], names[1]), args.worn, args))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
