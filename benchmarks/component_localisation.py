"""Which single-component failures can the shipped sensors localise? (issue 13)

Part 1 (always, about 2 s): on the linearised hst_trailer (expected spectra on the rig's
random track, 300 km/h), every yaw damper, secondary vertical damper side and primary
vertical damper (axlebox) at ``--fraction`` of its nominal damping, one at a time
(per-component parameters ``<parameter>@<component>``). Prints each failure's rms
spectral change per channel and, for chosen pairs, the angle between their signatures
over all channels, the carbody and the bogie-frame channels
(:mod:`susp_bo.rig.localisation`: cos θ = −posterior correlation of a joint fit).

Part 2 (``--calibrate``): a q = 2 calibration of two per-component parameters
(default: left and right yaw damper of the front bogie), the first worn to
``--worn`` of nominal, with the real loop (:func:`susp_bo.calibration.loop.calibrate`)
on the fast path of ``benchmarks/coverage.py`` (linearised rig, ν seeded German-PSD
tracks, white noise ``--noise`` m/s², paired error model, demo settings, budget
``--budget``), plus the exact-likelihood posterior on a ``--grid`` x ``--grid`` grid of
C_w (no surrogate) as the reference.

Commands and measured figures (issue 13 session, 2 shared cores)::

    python benchmarks/component_localisation.py

Part 1 (fraction 0.5), rms dB over 0.3–20 Hz, largest channels:

- yaw damper (any one): ≤ 0.14 dB in every channel (carbody lateral 0.07–0.11, bogie
  lateral of its own bogie 0.14 / 0.11): a single yaw damper at 50 % barely shows on
  tangent track at 300 km/h in the linear model;
- secondary vertical damper: carbody vertical 0.4–1.7 dB; bogie vertical of its bogie
  1.24–1.29 dB on the sensor's (left) side, 0.16–0.17 dB on the other side;
- primary vertical damper (one axlebox): carbody vertical up to 2.0–2.5 dB (nearest
  end), bogie vertical 0.31–0.59 dB (own bogie), nothing on the other bogie.

Pairs (cos θ all / carbody / bogie channels):

- left vs right, same bogie: carbody cos = 1.000 for every type (mirror symmetry: the
  carbody sensors sit on the centre line) — the carbody cannot tell sides apart. Only
  the bogie-frame sensors (on the left side) break it: yaw 0.988 / 1.000 / 0.972 (not
  localisable: the difference left is 0.002 dB rms), secondary vertical 0.865 / 1.000 /
  −0.19 (weak on all channels; 0.5 dB rms distinct part), primary vertical (wheelset 1)
  0.959 / 1.000 / −0.50 (weak).
- front vs rear bogie: localisable for every type (yaw 0.32 / 0.44 / 0.10; secondary
  vertical 0.06 / 0.07 / 0.01; primary wheelset 1 vs 3 0.58 / 0.61 / −0.005);
  leading vs trailing axle of one bogie (primary 1 vs 2): 0.73 / 0.75 / −0.12.

    python benchmarks/component_localisation.py --calibrate

Part 2: see the end of this docstring (filled in from the run).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # small matrices: threads only contend (2 shared cores)

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import importlib.util  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from types import ModuleType  # noqa: E402

import numpy as np  # noqa: E402

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


def _coverage_module() -> ModuleType:
    """benchmarks/coverage.py (its fast-path problem), loaded by path."""
    path = Path(__file__).with_name("coverage.py")
    module_spec = importlib.util.spec_from_file_location("susp_bo_sbc_coverage", path)
    assert module_spec is not None and module_spec.loader is not None
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[module_spec.name] = module
    module_spec.loader.exec_module(module)
    return module


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
    coverage = _coverage_module()
    cal = component_spec(spec, names)
    truth = cal.calibration_reference * np.array([worn, 1.0])
    options = coverage.Options(
        nu=args.nu, noise=args.noise, seed=0, error=args.error, budget=args.budget,
        smoke=False, local_search=True,
    )  # fmt: skip
    problem = coverage.FastPathProblem(cal, dict(zip(names, truth.tolist())), options, seed=7)
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
    settings = coverage.demo_settings(options, 0)
    started = time.perf_counter()
    result = coverage.calibrate(problem, bounds, names, settings, progress=False)
    draws = result.draws.reshape(-1, 2)
    c = np.corrcoef(draws.T)[0, 1]
    interval = np.asarray(result.summary.interval95)
    inside = (interval[:, 0] <= truth) & (truth <= interval[:, 1])
    verdict = None if result.reliability is None else result.reliability.verdict
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
    if args.calibrate:
        names = tuple(n.strip() for n in args.pair.split(","))
        if len(names) != 2:
            parser.error(f"--pair: got {args.pair!r}; expected two names a,b")
        print()
        print(calibration_study(spec, (names[0], names[1]), args.worn, args))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
