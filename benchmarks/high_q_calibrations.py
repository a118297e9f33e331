"""Per-component and high-dimensional calibrations (q = 8–14): trusted and wrong, or refused?

Session 30's outside probe (helper-28), kept as a benchmark. Every case is the real loop on
the linearised fast path (:mod:`fast_path`: the demo's settings with the local phase, the
truth's runs synthesised with sensor noise, ν = 3 and 0.01 m/s² unless the case says
otherwise) on a rig whose calibration set is per-component parameters (``<parameter>@
<component>``, README "Per-component parameters") next to type-level ones: four yaw dampers
per side, mirror-symmetric pairs with and without measured tracks (``paired`` /
``unpaired``), q = 13–14 mixes, truths at or near a bound, parameters with no effect, and
budgets from below the minimum to 600. A truth given as ``x0.5`` is half the rig's
reference; ``name=value:lower:upper`` sets the admissible interval too.

A result is *trusted and wrong* when it is ``trusted`` with some |z| > 3, z = (posterior
mean − truth) / posterior sd. Usage::

    python benchmarks/high_q_calibrations.py --out OUT                 # every case, ~100 min
    python benchmarks/high_q_calibrations.py --out OUT --cases q9_yaw4_paired_b300

One JSON a case in ``OUT`` (a finished case is not rerun), a summary on stdout; exit status
1 when any result is trusted and wrong.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fast_path import FastPathProblem, Options, demo_settings

from susp_bo.calibration.budget import BudgetTooSmallError, budget_requirement
from susp_bo.calibration.likelihood import expected_log_likelihood_at_truth
from susp_bo.calibration.loop import calibrate
from susp_bo.rig.components import split_component_name
from susp_bo.rig.spec import CalibrationParameter, RigSpec, load_rig_spec

_YAW4 = (
    "yaw_damper_damping@bogie_front_left=x0.5,yaw_damper_damping@bogie_front_right=x1,"
    "yaw_damper_damping@bogie_rear_left=x1,yaw_damper_damping@bogie_rear_right=x0.5,"
)
_TYPE5 = (
    "primary_vertical_stiffness=x1.1,primary_vertical_damping=x0.9,"
    "secondary_vertical_stiffness=x1.05,secondary_vertical_damping=x0.85,"
    "secondary_lateral_damping=x1.15"
)
_SVD4_YAW4 = (
    "secondary_vertical_damping@bogie_front_left=x1,"
    "secondary_vertical_damping@bogie_front_right=x0.5,"
    "secondary_vertical_damping@bogie_rear_left=x1,secondary_vertical_damping@bogie_rear_right=x1,"
    "yaw_damper_damping@bogie_front_left=x1,yaw_damper_damping@bogie_front_right=x1,"
    "yaw_damper_damping@bogie_rear_left=x0.5,yaw_damper_damping@bogie_rear_right=x1,"
)
_PVD8 = ",".join(
    f"primary_vertical_damping@wheelset_{k}_{side}={truth}"
    for k, side, truth in (
        (1, "left", "x0.5"), (1, "right", "x1"), (2, "left", "x1"), (2, "right", "x1"),
        (3, "left", "x1"), (3, "right", "x0.5"), (4, "left", "x1"), (4, "right", "x1"),
    )
)  # fmt: skip
_Q14 = (
    ",".join(
        f"primary_vertical_damping@wheelset_{k}_{side}={truth}"
        for k, side, truth in (
            (1, "left", "x1"),
            (1, "right", "x1"),
            (2, "left", "x0.5"),
            (2, "right", "x1"),
            (3, "left", "x1"),
            (3, "right", "x1"),
            (4, "left", "x1"),
            (4, "right", "x1.2"),
        )
    )
    + ",secondary_vertical_damping@bogie_front_left=x1,"
    "secondary_vertical_damping@bogie_front_right=x1,secondary_vertical_damping@bogie_rear_left=x1,"
    "secondary_vertical_damping@bogie_rear_right=x0.5,secondary_lateral_damping=x0.9,"
    "anti_roll_bar_stiffness=x1.1"
)
PARAMETER_SETS = {
    "yaw4": _YAW4 + _TYPE5,
    "q13": _SVD4_YAW4 + "primary_vertical_stiffness=x0.95,primary_vertical_damping=x1.1,"
    "secondary_vertical_stiffness=x1.1,secondary_lateral_damping=x0.9,anti_roll_bar_stiffness=x1.2",
    "near_bound": _YAW4.replace("bogie_front_left=x0.5", "bogie_front_left=550000") + _TYPE5,
    "at_bound": _YAW4.replace("bogie_front_left=x0.5", "bogie_front_left=501000") + _TYPE5,
    "series": _YAW4.replace("bogie_rear_right=x0.5", "bogie_rear_right=x1")
    + "yaw_damper_series_stiffness@bogie_front_left=1.5e7:5e6:2e7,"
    "primary_vertical_stiffness=x1.1,secondary_vertical_damping=x0.85,"
    "secondary_lateral_damping=x1.15",
    "pvd8": _PVD8,
    "flat_q11": _YAW4 + _TYPE5 + ",yaw_damper_knee@bogie_front_left=0.02:0.005:0.03,"
    "contact_flange_gap=0.012:0.005:0.015",
    "q14": _Q14,
}
"""Parameter set name -> ``name=truth[:lower:upper],...`` (truth ``xF``: F × reference)."""

CASES: dict[str, dict[str, Any]] = {
    "q9_yaw4_paired_b86": {"set": "yaw4", "factor": 1.5},
    "q9_yaw4_paired_b114": {"set": "yaw4", "budget": 114},
    "q9_yaw4_paired_b172": {"set": "yaw4", "budget": 172},
    "q9_yaw4_paired_b300": {"set": "yaw4", "budget": 300},
    "q9_yaw4_paired_b300_d11": {"set": "yaw4", "budget": 300, "data_seed": 11, "seed": 1},
    "q9_yaw4_paired_b300_d12": {"set": "yaw4", "budget": 300, "data_seed": 12, "seed": 2},
    "q9_yaw4_unpaired_b114": {"set": "yaw4", "budget": 114, "error": "unpaired"},
    "q9_yaw4_unpaired_b300": {"set": "yaw4", "budget": 300, "error": "unpaired"},
    "q9_yaw4_unpaired_b600": {"set": "yaw4", "budget": 600, "error": "unpaired"},
    "q9_yaw4_paired_nu2_noise05_b300": {"set": "yaw4", "budget": 300, "nu": 2, "noise": 0.05},
    "q9_below_minimum_b40": {"set": "yaw4", "budget": 40},
    "q9_below_minimum_b40_allowed": {"set": "yaw4", "budget": 40, "allow_small": True},
    "q9_near_bound_b300": {"set": "near_bound", "budget": 300},
    "q9_at_bound_b300": {"set": "at_bound", "budget": 300},
    "q8_series_b300": {"set": "series", "budget": 300},
    "q8_pvd8_paired_b300": {"set": "pvd8", "budget": 300},
    "q8_pvd8_paired_b600": {"set": "pvd8", "budget": 600},
    "q8_pvd8_unpaired_b400": {"set": "pvd8", "budget": 400, "error": "unpaired"},
    "q11_no_effect_b300": {"set": "flat_q11", "budget": 300},
    "q13_paired_b77": {"set": "q13", "budget": 77},
    "q13_paired_b154": {"set": "q13", "budget": 154},
    "q13_paired_b400": {"set": "q13", "budget": 400},
    "q13_paired_b400_d11": {"set": "q13", "budget": 400, "data_seed": 11, "seed": 1},
    "q13_unpaired_b400": {"set": "q13", "budget": 400, "error": "unpaired"},
    "q13_below_minimum_b60_allowed": {"set": "q13", "budget": 60, "allow_small": True},
    "q14_paired_b164": {"set": "q14", "budget": 164},
    "q14_paired_b500": {"set": "q14", "budget": 500},
}
"""Case name -> parameter set and settings (defaults: paired, ν = 3, 0.01 m/s², data seed
7, loop seed 0; ``factor`` × the minimum budget when no ``budget``)."""


def type_name(name: str, spec: RigSpec) -> str:
    """The rig parameter ``name`` sets: its type's for ``<parameter>@<component>``."""
    return split_component_name(name, spec.parameters)[0] if "@" in name else name


def parse_parameters(
    text: str, spec: RigSpec
) -> tuple[list[str], np.ndarray, dict[str, tuple[float, float]]]:
    """Names, truths (q,) and explicit admissible intervals from a parameter-set string."""
    names, truths, custom = [], [], {}
    reference = dict(spec.parameters)
    for item in text.split(","):
        name, value = (part.strip() for part in item.split("="))
        fields = value.split(":")
        if len(fields) == 3:
            custom[name] = (float(fields[1]), float(fields[2]))
        truth = fields[0]
        truths.append(
            float(reference[type_name(name, spec)]) * float(truth[1:])
            if truth.startswith("x")
            else float(truth)
        )
        names.append(name)
    return names, np.array(truths), custom


def case_spec(spec: RigSpec, names: list[str], custom: dict[str, tuple[float, float]]) -> RigSpec:
    """``spec`` calibrating ``names``: a component takes its type's interval and unit, unless
    ``custom`` gives one (then the unit is "-")."""
    entries = []
    for name in names:
        base = type_name(name, spec)
        if name in custom:
            lower, upper = custom[name]
            entries.append(
                CalibrationParameter(name, lower, upper, spec.parameters[base], "-", name)
            )
            continue
        shared = next(c for c in spec.calibration if c.name == base)
        entries.append(
            CalibrationParameter(
                name, shared.lower, shared.upper, shared.reference, shared.unit, name
            )
        )
    return dataclasses.replace(spec, calibration=tuple(entries))


def run_case(name: str, case: dict[str, Any]) -> dict[str, Any]:
    """One calibration with a known truth; the record the summary reads."""
    base = load_rig_spec("hst_trailer")
    names, truth, custom = parse_parameters(PARAMETER_SETS[case["set"]], base)
    spec = case_spec(base, names, custom)
    bounds = spec.calibration_bounds
    q = len(names)
    options = Options(
        nu=case.get("nu", 3),
        noise=case.get("noise", 0.01),
        seed=case.get("seed", 0),
        error=case.get("error", "paired"),
        budget=200,
        smoke=False,
        local_search=True,
    )
    first = demo_settings(options, 0)
    requirement = budget_requirement(
        q, first.initial_design_size, first.batch_size, first.check_points
    )
    budget = case.get("budget") or round(requirement.minimum * case["factor"])
    options = dataclasses.replace(options, budget=budget)
    settings = dataclasses.replace(
        demo_settings(options, 0), allow_small_budget=bool(case.get("allow_small", False))
    )
    record: dict[str, Any] = {
        "case": name, **case, "q": q, "names": names, "truth": truth.tolist(),
        "budget": budget, "minimum": requirement.minimum,
    }  # fmt: skip
    started = time.perf_counter()
    problem = FastPathProblem(
        spec, dict(zip(names, truth.tolist())), options, seed=case.get("data_seed", 7)
    )
    at_truth = expected_log_likelihood_at_truth(
        problem.error, problem.measured, spec.spectrum.frequencies_hz()
    )
    try:
        result = calibrate(
            problem,
            bounds,
            names,
            settings,
            progress=False,
            expected_at_truth=at_truth if all(map(math.isfinite, at_truth)) else None,
        )
    except BudgetTooSmallError as error:
        return record | {"refused": str(error), "seconds": time.perf_counter() - started}
    summary = result.summary
    mean, sd = np.asarray(summary.mean), np.asarray(summary.sd)
    interval = np.asarray(summary.interval95)
    inside = (interval[:, 0] <= truth) & (truth <= interval[:, 1])
    reliability = result.reliability
    assert reliability is not None
    return record | {
        "mean": mean.tolist(),
        "sd": sd.tolist(),
        "interval95": interval.tolist(),
        "inside": inside.tolist(),
        "z": ((mean - truth) / sd).tolist(),
        "verdict": reliability.verdict,
        "reasons": list(reliability.codes),
        "sentence": reliability.sentence,
        "r_hat_max": float(np.max(summary.r_hat)),
        "n_evaluations": int(result.n_evaluations),
        "seconds": time.perf_counter() - started,
    }


def summary_lines(records: list[dict[str, Any]]) -> list[str]:
    """One line a case, then the counts: trusted, their intervals inside, trusted and wrong."""
    lines = []
    trusted = inside = total = wrong = 0
    for r in records:
        if "refused" in r:
            lines.append(f"{r['case']:34s} q={r['q']:2d} budget {r['budget']:4d}: refused")
            continue
        worst = max(abs(z) for z in r["z"])
        lines.append(
            f"{r['case']:34s} q={r['q']:2d} budget {r['budget']:4d} (min {r['minimum']}): "
            f"{sum(r['inside'])}/{r['q']} inside, max |z| {worst:.2f}, {r['verdict']} "
            f"{','.join(r['reasons'])}"
        )
        if r["verdict"] == "trusted":
            trusted += 1
            inside += sum(r["inside"])
            total += r["q"]
            wrong += worst > 3.0
    lines.append(
        f"trusted {trusted}/{len(records)}; their intervals holding the truth {inside}/{total}; "
        f"trusted and wrong (|z| > 3): {wrong}"
    )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--cases", nargs="+", choices=sorted(CASES), default=list(CASES))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    records = []
    for name in args.cases:
        path = args.out / f"{name}.json"
        if not path.exists():
            print(f"high_q_calibrations: {name} ...", file=sys.stderr, flush=True)
            path.write_text(json.dumps(run_case(name, CASES[name]), indent=1) + "\n")
        records.append(json.loads(path.read_text()))
    lines = summary_lines(records)
    print("\n".join(lines))
    return 1 if not lines[-1].endswith(": 0") else 0


if __name__ == "__main__":
    raise SystemExit(main())
