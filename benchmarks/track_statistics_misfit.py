"""Does anything see a model error under the summary likelihood (tracks known only by statistics)?

:mod:`susp_bo.calibration.track_statistics`'s log L has no goodness-of-fit power of its
own (q summaries for q parameters: the fit zeroes them). What sees a model error is the
lack of fit between runs (:mod:`susp_bo.calibration.lack_of_fit`, limit F > 3), a fit
pinned at a bound of C_w (the verdict's ``at_bound``) and, since session 36, the test of
the summaries the fit does not use (:mod:`susp_bo.calibration.summary_misfit`, p <
``P_LIMIT``). This benchmark measures them at the exact summary fit (no
surrogate, no loop) on the linearised rig, with data from a vehicle that differs from the
model by one change (as :mod:`misspecified_model`: a conicity, a carbody bending mode, an
air-spring reservoir) or none:

1. a truth from the prior (``sbc_draw(seed, e)``, the demo's q = 7), ν = 3 runs of the
   changed vehicle on tracks the model does not know (noise 0.01 m/s²);
2. the model — the unchanged rig — on ν other track realizations, its summary error from
   the two-stage pilot (``track_statistics_pilot.two_stage_error``);
3. the Gauss–Newton fit of the summaries, its Laplace sd, z = (fit − truth) / sd, F and the
   summary misfit's p at the fit.

A fit is *wrong and unflagged* when some |z| > 3, F ≤ 3, p ≥ ``P_LIMIT`` and no parameter
sits at a bound; a *false alarm* is a flag (F > 3 or p < ``P_LIMIT``) on the unchanged
vehicle (``none``).
Usage::

    python benchmarks/track_statistics_misfit.py --experiments 6 --seed 34
    python benchmarks/track_statistics_misfit.py --experiments 16 --seed 36 --changes none \
        --noise 0.005 --fast-rig DIR

About 30–50 s a fit on one core (24 fits ≈ 15 min).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from coverage_pybullet import fast_rig
from fast_path import FastPathProblem, Options, sbc_draw
from track_statistics_pilot import summary_fit, two_stage_error, whitened_jacobian

from susp_bo.calibration.lack_of_fit import LIMIT, lack_of_fit_ratio
from susp_bo.calibration.summary_misfit import P_LIMIT, summary_misfit
from susp_bo.commands.demo import DEMO_RIG
from susp_bo.discrepancy.effects import with_effect
from susp_bo.rig.spec import RigSpec, load_rig_spec

CHANGES = {
    "none": None,
    "conicity_0.15": ("parameter", "contact_equivalent_conicity", 0.15),
    "conicity_0.12": ("parameter", "contact_equivalent_conicity", 0.12),
    "conicity_0.11": ("parameter", "contact_equivalent_conicity", 0.11),
    "carbody_bending_9hz": (
        "effect",
        "carbody_bending",
        {"frequency_hz": 9.0, "damping_ratio": 0.02},
    ),
    "air_spring_reservoir": (
        "effect",
        "air_spring_reservoir",
        {"stiffness_ratio": 3.0, "corner_frequency_hz": 1.0},
    ),
}
DEFAULT_CHANGES = ("none", "conicity_0.15", "carbody_bending_9hz", "air_spring_reservoir")
"""The changes run by default (the smaller conicities on request: ``--changes``)."""
NOISE_M_S2 = 0.01
"""Sensor noise (m/s² rms) by default (``--noise``)."""


def data_spec(spec: RigSpec, change: str) -> RigSpec:
    """The vehicle the data come from: the model's rig with one change, or the same."""
    what = CHANGES[change]
    if what is None:
        return spec
    kind, name, value = what
    if kind == "parameter":
        return spec.with_parameters({name: value})
    return with_effect(spec, name, value)


def fit(spec: RigSpec, change: str, seed: int, experiment: int, noise: float = NOISE_M_S2) -> dict:
    """One exact summary fit (module docstring)."""
    names, bounds = spec.calibration_names, spec.calibration_bounds
    span = bounds[1] - bounds[0]
    u_true, data_seed = sbc_draw(seed, experiment, len(names))
    truth = dict(zip(names, (bounds[0] + u_true * span).tolist()))
    options = Options(
        nu=3, noise=noise, seed=seed, error="unpaired", budget=None, smoke=False,
        unknown_tracks=True,
    )  # fmt: skip
    problem = FastPathProblem(data_spec(spec, change), truth, options, data_seed)
    problem.spec = spec  # the model lacks the change
    error, pilot = two_stage_error(problem, data_seed)
    u, converged = summary_fit(problem, error, np.array(pilot.first_fit))
    _, jac = whitened_jacobian(problem, error, u)
    z = (u - u_true) / np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))
    simulated = problem.spectra((bounds[0] + u * span)[None])[0]
    f = lack_of_fit_ratio(problem.measured, simulated)
    p = (
        math.nan
        if error.misfit is None
        else summary_misfit(problem.measured, simulated, error.misfit)[1]
    )
    return {
        "change": change,
        "experiment": experiment,
        "F": f,
        "p": p,
        "max_abs_z": float(np.max(np.abs(z))),
        "at_bound": bool(np.any((u <= 0.0) | (u >= 1.0))),
        "converged": converged and pilot.converged,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=6, help="truths per change")
    parser.add_argument("--seed", type=int, default=34, help="master seed of truths and data")
    parser.add_argument(
        "--changes", nargs="*", default=list(DEFAULT_CHANGES), choices=list(CHANGES)
    )
    parser.add_argument("--noise", type=float, default=NOISE_M_S2, help="sensor noise, m/s² rms")
    parser.add_argument(
        "--fast-rig",
        type=Path,
        default=None,
        metavar="DIR",
        help="the test suite's cheap variant of the demo's rig, written in DIR "
        "(coverage_pybullet.fast_rig: 8 s records, 4 s segments, 32 bands)",
    )
    args = parser.parse_args(argv)
    if args.experiments < 1:
        parser.error(f"--experiments: got {args.experiments}; expected an integer >= 1")
    if not args.noise > 0:
        parser.error(f"--noise: got {args.noise}; expected a sensor noise > 0 m/s² rms")
    spec = load_rig_spec(DEMO_RIG if args.fast_rig is None else fast_rig(args.fast_rig))
    records = []
    for change in args.changes:
        for e in range(args.experiments):
            started = time.perf_counter()
            r = fit(spec, change, args.seed, e, args.noise)
            records.append(r)
            print(
                f"{change:<22s} {e}: F {r['F']:.2f}, p {r['p']:.1e}, max |z| "
                f"{r['max_abs_z']:.1f}, at a bound "
                f"{r['at_bound']} ({time.perf_counter() - started:.0f} s)",
                file=sys.stderr,
                flush=True,
            )
    print(
        f"lack-of-fit limit {LIMIT:g}, summary misfit p < {P_LIMIT:g}; seed {args.seed}, "
        f"noise {args.noise:g} m/s², "
        f"{args.experiments} truths per change"
    )
    unflagged = 0
    for change in args.changes:
        rs = [r for r in records if r["change"] == change]
        f = [r["F"] for r in rs]
        p = [r["p"] for r in rs]
        z = [r["max_abs_z"] for r in rs]
        flagged = [r["F"] > LIMIT or r["p"] < P_LIMIT for r in rs]
        bad = [
            r
            for r, flag in zip(rs, flagged)
            if r["max_abs_z"] > 3 and not flag and not r["at_bound"]
        ]
        unflagged += len(bad) if change != "none" else 0
        print(
            f"  {change:<22s} F {min(f):.2f}–{max(f):.2f} ({sum(x > LIMIT for x in f)} above), "
            f"p {min(p):.1e}–{max(p):.1e} ({sum(x < P_LIMIT for x in p)} below), "
            f"flagged {sum(flagged)}/{len(rs)}, "
            f"max |z| {min(z):.1f}–{max(z):.1f} ({sum(x > 3 for x in z)} > 3), "
            f"{sum(r['at_bound'] for r in rs)} at a bound, {len(bad)} wrong and unflagged"
        )
    print(f"wrong and unflagged under a model error: {unflagged}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
