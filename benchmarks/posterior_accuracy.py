"""Posterior accuracy (MMTV) versus number of log L evaluations, against peers.

For each analytic target of ``susp_bo.calibration.test_functions`` (exact posterior
known) and each budget, this script runs in the same process:

- ``susp_bo``: :func:`susp_bo.calibration.loop.calibrate` with default settings
  (raw log L kriged, ``transform="none"``) — the tool;
- ``susp_bo-auto``: the same with ``transform="auto"`` (warping chosen by leave-one-out
  at each refit) — with the next one, the measurement behind the dynamic-range choice;
- ``susp_bo-logdef``: the same with ``transform="log_deficit"`` always;
- ``susp_bo-constmean``: the same with ``SurrogateSettings(mean="constant")`` (the
  default "auto" picks the constant or the negative-quadratic prior mean by leave-one-out
  at each refit);
- ``susp_bo-ego``: EGO only (no posterior refinement), i.e. the paper's method
  made batch-parallel;
- ``susp_bo-noise``: the default with ``SurrogateSettings(noise="learned")`` (the GP
  fits an observation noise of log L, and its ``mean="auto"`` is then the full
  quadratic, since session 11; for a stochastic simulator);
- ``susp_bo-known-noise``: the same with the noise held at 1 nat
  (``noise_prior_width=0.02`` around the default ``noise_sd_guess`` of 1 nat, which is
  the noisy target's noise sd): the information PyVBMC gets on that target;
- ``susp_bo-optimistic``: the default with ``refine_optimism=2.0`` (refinement candidates
  from the optimistic posterior exp(E[L̃]), weight exp(E[log L̃] + 2 sd − max));
- ``susp_bo-kauto``: the default with ``SurrogateSettings(kernel="auto")`` (the Matérn
  and the pairwise additive kernel fitted at every refit, the better leave-one-out score
  kept: :mod:`susp_bo.calibration.additive_kernel`);
- ``pyvbmc``: PyVBMC (Acerbi's VBMC) at ``max_fun_evals`` = the same budget, on the
  same unit-cube log density with the same bounds (if ``pyvbmc`` is installed); on a
  noisy target it is told the noise sd (``specify_target_noise``);
- ``bolfi``: ELFI's BOLFI (default LCB acquisition, GP on the discrepancy
  log(−log L), ELFI's threshold posterior; see :func:`peer_samplers.run_bolfi`), if ``elfi`` is
  importable. It is not installed in the project venv (its pins would downgrade
  matplotlib to 3.8, below pyvbmc's floor, so pyvbmc cannot be installed in the same
  pip command); install it in a separate venv, in this order (elfi 0.8.8, GPy 1.15.0
  work with numpy 2.4)::

      python3 -m venv /work/elfi-venv
      /work/elfi-venv/bin/pip install torch==2.13.0
      /work/elfi-venv/bin/pip install -e ".[bench]"
      /work/elfi-venv/bin/pip install elfi
      /work/elfi-venv/bin/python benchmarks/posterior_accuracy.py --methods bolfi

Noisy targets (:class:`NoisyTarget`) get a fresh noise stream per run, seeded by the
run's seed. Rows are written to ``--out`` after every run; ``--resume`` keeps the rows
already there (long comparisons can be run one method or seed at a time into one file).

The script prints MMTV (mean marginal total variation against the exact marginals; 0 is
perfect, ≈0.005 is the floor of 1e5 exact draws), the evaluations actually used and
the wall time. Ratios are against PyVBMC in the same run.

Example (the figures of the report; one seed is not enough to rank methods — at 25 %
of the budget the MMTV of one run varies by 3x between seeds for every method):

    python benchmarks/posterior_accuracy.py --methods susp_bo pyvbmc --seeds 0 1 2

Measured (session 2, mean MMTV over seeds 0–2; BOLFI seed 0 only, from its own venv)
at 25 / 50 / 100 % of 50 (q + 2) evaluations. ``susp_bo`` = the default (prior mean
"auto"; measured with a least-squares start by ``torch.linalg.lstsq``, since replaced by
the normal equations for reproducibility); ``constant`` = ``mean="constant"`` earlier in
the session (7-D Gaussian rows before the surrogate check existed; oscillator not run);
PyVBMC 1.5.0 rows do not depend on this code:

    target                  constant         susp_bo            pyvbmc             bolfi
    banana_2d               .044/.008/.006   .021/.009/.006     .043/.027/.031     .15/.14/.14
    correlated_gaussian_7d  .023/.010/.007   .024/.009/.007     .045/.010/.008     .69/.66/.29
    weakly_identified_7d    .022/.006/.006   .009/.006/.006     .032/.017/.024     .15/.06/.06
    oscillator_2d           —                .011/.007/.006     .010/.008/.009     .40/.12/.13

Surrogate robustness (issue 10, part 3; session 4). Targets of
:mod:`susp_bo.calibration.test_functions.robustness`, full budget 50 (q + 2), batches
of 8, one process at a time under ``nice -n 10`` on 2 cores shared with CI runs (load
5–8), each command appending to one file::

    python benchmarks/posterior_accuracy.py --budget-fractions 1.0 --out rows.json \
        --resume --targets curved_chain_5d student_t_6d trimodal_5d noisy_gaussian_7d \
        --methods susp_bo susp_bo-noise pyvbmc --seeds 0 1 2

(run as several such commands, one target/method/seed group at a time; the PyVBMC runs
not listed below were not reached: PyVBMC took 34 min for one 350-evaluation run here).
MMTV, median / worst seed over the seeds run; target: <= 0.05 on every seed and no worse
than PyVBMC:

    target             evals  susp_bo             susp_bo-noise       PyVBMC 1.5.0  target
    curved_chain_5d      350  .128 / .136         —                   .152 (s 0)    NOT MET
    student_t_6d         400  .033 / .036         —                   not run       <=.05 met
    trimodal_5d          350  .178 / .191         —                   not run       NOT MET
    noisy_gaussian_7d    450  .114 (seed 0 only)  .055 / .060         not run       NOT MET

Per seed 0 / 1 / 2: curved .136 .121 .128; Student-t .036 .032 .033; trimodal .164
.191 .178; noisy with the learned noise .055 .037 .060. "NOT MET": worst seed above
0.05. The comparison with PyVBMC is made on the curved target only (one PyVBMC seed,
below all three of ours); on the others it was not run.

MMTV here uses the KDE bandwidth min(Silverman, AMISE-optimal for the exact marginal)
(:func:`marginal_total_variation`; Silverman alone blurs the trimodal marginals: 0.03 of
MMTV from 4e4 exact draws). It changes the earlier targets' scores only where the oracle
is smaller (one component of banana_2d, two of weakly_identified_7d, by 8–17 %).

Wall time per susp_bo run 120–240 s (learned noise 306–700 s). Diagnosis of the misses
(seed 0, same settings, reproduced bit for bit):

- trimodal_5d: the surrogate is right and the sampler is not. All three modes were
  found (130 / 48 / 45 evaluations within Mahalanobis² < 20 of each); the final draws put
  0.70 / 0.13 / 0.17 of their mass in them against 0.5 / 0.3 / 0.2, and with the draws
  reweighted to the exact mode weights the MMTV is 0.025. The random-walk chains do not
  cross between modes 9+ sd apart, so the weights are set by where the chains start.
  (The MH kernel on the *exact* trimodal density from exact starts: MMTV 0.024–0.031 per
  parameter; on the curved chain 0.009–0.012.)
- curved_chain_5d: the surrogate is wrong in the banana's arms: at exact posterior draws
  it is 11 nats too low at the 5 % quantile (median-centred), and the surrogate's draws
  reweighted by exp(log L − log L̃) still score 0.065–0.107 per parameter (they do not
  cover the arms). The held-out check said ``ok`` on this run (a silent failure, as in
  the issue): its edge points along the principal directions do not probe the arms.
- noisy_gaussian_7d: the learned noise halves the error of the fixed default, but the
  worst seed is at 0.060.

Session 5 (25 Nov 2026): every row now carries the reliability verdict, and the summary
counts the runs that were ``trusted`` with MMTV > 0.05 (the silent failures).

- Before any change (the code of session 4): trimodal seeds 0 / 1: MMTV .164 / .191, both
  ``not_trusted`` (``poor_mixing``; seed 0 also ``not_converged``) — the verdict was right,
  but only because the random-walk chains could not cross between modes.
- Mode jumps in the MH kernel (:mod:`susp_bo.calibration.mode_jumps`; a frozen Gaussian
  mixture over the modes found half-way through warm-up, as an independence proposal with
  its MH correction). On the *exact* trimodal density from starts shared 70 / 13 / 17 %
  (tests/calibration/test_mode_jumps.py) the mode shares come out within 0.03 of the
  exact 0.47 / 0.30 / 0.23 and R-hat falls from 4.8 to 1.07. Through the whole loop
  (first version of the mode finder): seed 0 MMTV **.020**, trusted; seed 1 **.188,
  trusted — a silent failure**: the search had evaluated only the fringe of the third
  mode, so the surrogate is 32 nats too low over its bulk (median, at exact draws) and the
  third mode keeps 5 % of the mass against 23 %; now that the chains mix, R-hat no longer
  flags it, and no other rule saw it (held-out check ok, LOO errors at the best points
  below 2 nats). Seed 2: .181, ``not_trusted`` (``poor_mixing``).
- Hence the reliability reason ``multimodal``: two or more separated modes found by the
  sampler make a result ``not_trusted`` (the mass between modes rests on the surrogate
  where the check does not look). With it (final code, ``python
  benchmarks/posterior_accuracy.py --budget-fractions 1.0 --targets trimodal_5d
  curved_chain_5d --methods susp_bo --seeds 0 1 2``, 2026-11-25): trimodal seeds 0 / 1 /
  2 MMTV **.023** / .188 / .187, all ``not_trusted`` (``multimodal``; seed 2 also
  ``poor_mixing``) — seed 0 right and refused, seed 1's silent failure now refused; curved
  chain .136 / .121 / .122, all ``not_trusted`` (``not_converged``; seed 2 also
  ``multimodal``). Trusted with MMTV > 0.05: **0 of 6** (1 of 6 with the intermediate
  code). Noisy Gaussian (intermediate code) .124 / .129, ``not_trusted``. The MMTV <= 0.05
  target on every seed is **still not met** on the trimodal (the surrogate of seeds 1–2
  misses mass), the curved chain and the noisy target.

Session 7 (25 Nov 2026): the basin phase (:mod:`susp_bo.calibration.basin_search`,
default on). Trimodal seed 1 above had evaluated the third mode only at its fringe (3
points at Mahalanobis² 20–50 from its centre, none nearer: EGO seeks the global maximum
and leaves a lower mode once it knows a higher one); the surrogate was 35 nats too low over
that mode's bulk and the draws gave it 0 % of the mass. When EGO ends, every evaluated
point within 20 nats of the best now climbs the surrogate's mean; climbs that end at a
peak away from the best point's mark other basins, and from each the loop runs a local
qLogEI climb (TuRBO-like box around the basin's best point, its own incumbent) with a
share of up to 40 % of the evaluations left. ``python benchmarks/posterior_accuracy.py
--budget-fractions 1.0 --targets trimodal_5d curved_chain_5d student_t_6d --methods
susp_bo --seeds 0 1 2`` (2 shared cores; final code):

    target             evals  seeds 0 / 1 / 2          median / worst   before (session 5)
    trimodal_5d          350  .023 / .023 / .020       .023 / .023      .023 / .188 / .187
    curved_chain_5d      350  .116 / .138 / .158       .138 / .158      .136 / .121 / .122
    student_t_6d         400  .036 / .032 / .033       .033 / .036      .036 / .032 / .033

(Student-t: measured on the phase's previous version, which differed only in skipping
fewer lower points of seen basins.) Trimodal: **MMTV <= 0.05 on every seed** (seed 1,
inspected on that previous version, MMTV .024: three climbs, 75
evaluations in all — 32 from −64.7 to −60.5 in the second mode, 16 at the first mode's
top, and 27 from the third mode's fringe point at log L −70.4 to its top at −60.8; the
surrogate's error at exact posterior draws, 5 % quantile, went from −42.8 to −0.7 nats);
the verdicts stay ``not_trusted`` with ``multimodal``: the rule is kept, since a mode that
no evaluation came near would still be missed in silence). The curved chain is **still
not met** and made worse: it has no second mode, but its surrogate shows local peaks along
the banana's arms, and the climbs there take evaluations from the refinement (median .138
against .122 before; seeds 1 and 2 worse, seed 0 better). The Student-t target is
unchanged (the same MMTV to the printed digits). PyVBMC on the
trimodal and Student-t targets: not run (a 350-evaluation PyVBMC run took 34 min here),
so "never worse than PyVBMC" is shown on the curved chain only (PyVBMC .152, seed 0).
A unimodal paired problem is not changed at all: a fast-path SBC experiment
(``coverage.py --nu 2``, experiment 0) gave a bit-identical record with and without the
phase (all fields but the wall time).

Session 8 (25 Nov 2026, 2 cores shared with CI runs and an SBC; each command appends to
its own ``--out`` file):

- Noisy 7-D Gaussian with the learned noise, the code of this session (basin phase
  included), ``python benchmarks/posterior_accuracy.py --budget-fractions 1.0 --targets
  noisy_gaussian_7d --methods susp_bo-noise --seeds 0 1 2``: MMTV **.036 / .043 / .046**
  (median .043, worst .046; session 4: .055 / .037 / .060), 264–271 s a run; all three
  ``not_trusted`` (``not_converged``: the refinement criterion, a posterior mean of the GP
  sd, cannot fall below 0.02 nats when every evaluation carries 1 nat of noise).
  **MMTV <= 0.05 on every seed: met** with ``SurrogateSettings(noise="learned")``; the
  default (``noise="fixed"``, right for a deterministic simulator) was .114 on seed 0.
  PyVBMC on this target: not run this session either (a run was started and stopped
  unfinished after 25 min on the shared cores); "never worse than PyVBMC" is still
  shown on the curved chain only.
- Curved chain: ``refine_optimism`` (opt-in; ``susp_bo-optimistic`` = 2.0). Diagnosis
  first (seed 0, the default): at 3 000 exact posterior draws the surrogate is ≥ 5 nats
  too low at 10 % of them, all in the arms (|x_1| 0.6–2.2 sd), 0.07–0.14 (unit cube) from
  the nearest evaluation, where the GP's own sd is 2.8–6.1 nats: the GP knows it does
  not know, but refinement picks among draws of the plug-in posterior, which the
  too-low arms exclude, and weighs them by exp(E[log L̃]). With κ = 2 the candidates come
  from the optimistic exp(E[L̃]) posterior too and the weight is exp(E[log L̃] + 2 sd):
  the share of draws ≥ 5 nats too low falls to 5 %. ``python
  benchmarks/posterior_accuracy.py --budget-fractions 1.0 --targets curved_chain_5d
  --methods susp_bo-optimistic susp_bo --seeds 0 1 2``:

      method                seeds 0 / 1 / 2        median / worst   wall time a run
      susp_bo (default)     .136 / .130 / .160     .136 / .160      156–373 s
      susp_bo-optimistic    .073 / .104 / .153     .104 / .153      350–2 000 s (load)

  (The default's figures on this Intel machine differ from session 7's .116 / .138 / .158
  on another CPU: the GP's last bits, then the search's path, differ across CPUs.) All six
  ``not_trusted`` (``not_converged`` with ``poor_mixing`` or ``multimodal``): no silent
  failure.

  Better on every seed, still **not met** (target <= 0.05 on every seed); kept opt-in
  because every measured figure of the paired problems (demo, SBC) is the default's, and
  a default change needs them re-measured.

Session 9 (26 Nov 2026): PyVBMC 1.5 on the robustness targets, the same benchmark and
budgets, one command per group (each appending to its own ``--out``; 2 cores shared
with demos, a test run and each other, so the wall times are upper bounds; PyVBMC stops
on its own criteria before the budget)::

    python benchmarks/posterior_accuracy.py --budget-fractions 1.0 --methods pyvbmc \
        --targets student_t_6d trimodal_5d noisy_gaussian_7d curved_chain_5d --seeds 0 1 2

    target             PyVBMC seeds 0 / 1 / 2   evals     susp_bo (sessions 7–8)     met?
    student_t_6d       .376 / .357 / .274       310       .036 / .032 / .033         yes
    trimodal_5d        .413 / .413 / .413       85        .023 / .023 / .020         yes
    noisy_gaussian_7d  .046 / .028 / .024       165–180   .036 / .043 / .046 (noise) NO
                                                          .034 / .041 / .031 (known) NO
    curved_chain_5d    .152 / .129 / .138       185       .136 / .130 / .160         NO
                       (seed 0: session 4)                .073 / .104 / .153 (optim.)

(PyVBMC 85–535 s a run here.) "Never worse than PyVBMC" holds on the Student-t and
trimodal targets by a factor 8–21 (why PyVBMC stops at 85 evaluations on the trimodal
target, with the same MMTV on every seed, was not examined). It does **not** hold on the noisy
target: PyVBMC, told the noise sd (1 nat) through ``specify_target_noise``, beats
``susp_bo-noise``, which learns the noise level, on seeds 1 and 2 and in the median (.028
against .043; worst .046 both). Given the same information (``susp_bo-known-noise``: the
noise held at 1 nat by ``SurrogateSettings(noise_prior_width=0.02)``, new this session;
``--methods susp_bo-known-noise --targets noisy_gaussian_7d --seeds 0 1 2``, 460–470 s a
run): .034 / .041 / .031, median .034, worst .041 — better than the learned noise on every
seed and better than PyVBMC in the worst seed (.041 against .046) and on seed 0, still
worse on seeds 1 and 2 and in the median (.034 against .028): not met. All three
``not_trusted`` (``not_converged``). On the
curved chain the default is better in the median (.136 against .138) and worse on seeds
1 (by .001) and 2 and in the worst seed (.160 against .152); ``refine_optimism = 2`` is
better in the median (.104) and ties the worst (.153 against .152). None of the curved or
noisy runs meets MMTV <= 0.05 on every seed, PyVBMC's neither.

Oscillator at 50 evaluations over 10 seeds (susp_bo) vs 9 (PyVBMC): mean .0110 vs
.0106, median .0091 vs .0102 — a tie. Every other cell of susp_bo is below PyVBMC and
BOLFI; the constant mean ties PyVBMC on the banana at 50 and the Gaussian at 225.

Session 11 (26 Nov 2026): with a learned noise, ``mean="auto"`` is now the full
quadratic (:func:`susp_bo.calibration.surrogate_fit.auto_means`; it was the constant or
the diagonal quadratic by leave-one-out, which on noisy values kept the diagonal bowl
even where the full one followed log L 3.5x more closely). The noise hides the fine
structure a GP resolves on a deterministic log L; a correlated bowl as the prior mean
carries the posterior's shape and lets the noise average out over all evaluations. The
deterministic default (``noise="fixed"``) is unchanged (the smoke demo's result.json and
draws are bit-identical). Same machine, one command per group, 2 cores shared with an
SBC::

    python benchmarks/posterior_accuracy.py --budget-fractions 1.0 \
        --targets noisy_gaussian_7d --methods susp_bo-noise susp_bo-known-noise pyvbmc \
        --seeds 0 1 2

    noisy_gaussian_7d (450 evaluations)   seeds 0 / 1 / 2       median / worst  verdicts
    susp_bo-noise (learned noise)         .023 / .009 / .020    .020 / .023     3 trusted
    susp_bo-known-noise (held at 1 nat)   .020 / .022 / .022    .022 / .022     3 trusted
    PyVBMC 1.5, told the noise sd         .046 / .028 / .024    .028 / .046     175/165/180 evals
    (session 8–9: susp_bo-noise .036 / .043 / .046, known .034 / .041 / .031, all
    ``not_converged``)

MMTV <= 0.05 on every seed and below PyVBMC on every seed, in the median and the worst
seed: **met** for the noisy target, with the learned noise as well as the known one. The
verdict, which said ``not_converged`` on every noisy run before (the GP's sd over the
posterior stayed at 0.5–0.9 nats under 1 nat of noise, above the 0.3-nat criterion),
now says ``trusted``: with the bowl as the mean the GP's residual is small and its sd
falls below the criterion. (Both rows were first run as explicit
``mean="full_quadratic"`` methods; rerun as ``susp_bo-known-noise`` with the new ``auto``
on seeds 0–2 and as ``susp_bo-noise`` on seed 1, they gave the same MMTV to the last
bit.) The summary of these nine rows: ``susp_bo-noise`` median .0196, worst .0230, MET;
``susp_bo-known-noise`` median .0218, worst .0222, MET; PyVBMC median .0283, worst
.0458. 245–415 s a run for this tool, 223–389 s for PyVBMC.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from susp_bo.calibration.loop import CalibrationSettings, calibrate
from susp_bo.calibration.loop_step import torch_threads
from susp_bo.calibration.surrogate import SurrogateSettings
from susp_bo.calibration.test_functions import (
    TARGETS,
    NoisyTarget,
    Target,
    marginal_total_variation,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling peer_samplers.py
from peer_samplers import run_bolfi, run_pyvbmc

Runner = Callable[[Target, int, int], tuple[np.ndarray, int, str | None]]
"""(target, budget, seed) -> (draws, evaluations used, reliability verdict or None)."""
ROBUSTNESS_TARGETS = ("curved_chain_5d", "student_t_6d", "trimodal_5d", "noisy_gaussian_7d")
"""The targets of issue 10, part 3 (MMTV <= 0.05 at 50 (q + 2), never worse than PyVBMC)."""


def run_susp_bo(settings: CalibrationSettings) -> Runner:
    """Runner for this tool with the given settings (budget and seed filled in)."""

    def run(target: Target, budget: int, seed: int) -> tuple[np.ndarray, int, str | None]:
        s = replace(settings, max_evaluations=budget, seed=seed)
        result = calibrate(target, target.bounds, target.names, s, progress=False)
        reliability = result.reliability
        verdict = None
        if reliability is not None:
            codes = ",".join(r["code"] for r in reliability.reasons)
            verdict = reliability.verdict + (f" ({codes})" if codes else "")
        return result.samples, result.n_evaluations, verdict

    return run


def _runners(batch_size: int) -> dict[str, Callable[[], Runner]]:
    """Method name -> factory of its runner (built only when the method is asked for)."""
    base = CalibrationSettings(batch_size=batch_size)

    def with_surrogate(**kw: object) -> Callable[[], Runner]:
        return lambda: run_susp_bo(replace(base, surrogate=SurrogateSettings(**kw)))

    return {
        "susp_bo": lambda: run_susp_bo(base),
        "susp_bo-auto": with_surrogate(transform="auto"),
        "susp_bo-logdef": with_surrogate(transform="log_deficit"),
        "susp_bo-ego": lambda: run_susp_bo(replace(base, refine=False, max_ego_fraction=1.0)),
        "susp_bo-constmean": with_surrogate(mean="constant"),
        "susp_bo-noise": with_surrogate(noise="learned"),
        "susp_bo-known-noise": with_surrogate(noise="learned", noise_prior_width=0.02),
        "susp_bo-optimistic": lambda: run_susp_bo(replace(base, refine_optimism=2.0)),
        "susp_bo-kauto": with_surrogate(kernel="auto"),
        "pyvbmc": lambda: run_pyvbmc,
        "bolfi": lambda: run_bolfi,
    }


def summarize_rows(rows: list[dict], methods: list[str], threshold: float = 0.05) -> list[str]:
    """Lines of the summary: per (target, budget) and method the median / worst / mean MMTV
    over seeds, and for the robustness targets whether MMTV <= ``threshold`` on every seed
    and the median and the worst seed are no worse than PyVBMC's."""
    lines = [
        "Median / worst / mean MMTV over seeds (n = seeds); target: worst <= "
        f"{threshold} and median, worst <= PyVBMC's"
    ]
    for key in sorted({(r["target"], r["budget"]) for r in rows}):
        stats: dict[str, tuple[float, float, float, int]] = {}
        for method in methods:
            vals = [
                r["mmtv"] for r in rows if (r["target"], r["budget"], r["method"]) == (*key, method)
            ]
            if vals:
                stats[method] = (
                    float(np.median(vals)),
                    float(np.max(vals)),
                    float(np.mean(vals)),
                    len(vals),
                )
        ref = stats.get("pyvbmc")
        for method, (med, worst, mean, n) in stats.items():
            verdict = ""
            if method != "pyvbmc" and key[0] in ROBUSTNESS_TARGETS:
                ok = worst <= threshold
                if ref is None:
                    verdict = f"  <= {threshold}: {'yes' if ok else 'NO'}; PyVBMC not run"
                else:
                    ok = ok and med <= ref[0] and worst <= ref[1]
                    verdict = "  MET" if ok else "  NOT MET"
            lines.append(
                f"{key[0]:24s} {key[1]:5d} {method:18s} median {med:.4f} worst {worst:.4f} "
                f"mean {mean:.4f} (n={n}){verdict}"
            )
            mine = [r for r in rows if (r["target"], r["budget"], r["method"]) == (*key, method)]
            judged = [r for r in mine if r.get("verdict")]
            if judged:  # the honesty side: a trusted verdict on a posterior that is off
                silent = sum(r["verdict"] == "trusted" and r["mmtv"] > threshold for r in judged)
                trusted = sum(r["verdict"] == "trusted" for r in judged)
                lines.append(
                    f"{'':49s}verdict trusted {trusted}/{len(judged)}; trusted with MMTV > "
                    f"{threshold}: {silent}"
                )
    return lines


def main(argv: list[str] | None = None) -> int:
    """Runs the comparison and prints a table (and writes JSON with --out)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--targets", nargs="+", default=list(TARGETS), choices=list(TARGETS))
    parser.add_argument(
        "--budget-fractions",
        nargs="+",
        type=float,
        default=[0.25, 0.5, 1.0],
        help="budgets as fractions of 50 (q + 2)",
    )
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    factories = _runners(8)
    parser.add_argument(
        "--methods",
        nargs="+",
        default=["susp_bo", "susp_bo-auto", "susp_bo-logdef", "susp_bo-ego", "pyvbmc", "bolfi"],
        choices=list(factories),
    )
    parser.add_argument("--batch-size", type=int, default=8)
    parser.add_argument(
        "--out", help="write the rows as JSON to this file (rewritten after every run)"
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="with --out: keep the rows already in that file and skip their runs",
    )
    args = parser.parse_args(argv)

    factories = _runners(args.batch_size)
    runners: dict[str, Runner] = {}
    rows: list[dict] = []
    if args.resume and args.out:
        try:
            with open(args.out, encoding="utf-8") as fh:
                rows = json.load(fh)
        except FileNotFoundError:
            rows = []
    done = {(r["target"], r["budget"], r["method"], r["seed"]) for r in rows}
    print(
        f"{'target':24s} {'budget':>6s} {'method':12s} {'seed':>4s} {'evals':>5s} "
        f"{'MMTV':>7s} {'time s':>7s}",
        flush=True,
    )
    for name in args.targets:
        target = TARGETS[name]()
        full = 50 * (target.dim + 2)
        for frac in args.budget_fractions:
            budget = max(12, round(frac * full))
            for method in args.methods:
                for seed in args.seeds:
                    if (name, budget, method, seed) in done:
                        continue
                    run_target = (
                        target.reseeded(seed) if isinstance(target, NoisyTarget) else target
                    )
                    t0 = time.perf_counter()
                    try:
                        runner = runners.setdefault(method, factories[method]())
                        with torch_threads(1):
                            draws, used, verdict = runner(run_target, budget, seed)
                    except (ImportError, NotImplementedError) as exc:
                        print(f"{name:24s} {budget:6d} {method:12s} skipped: {exc}", flush=True)
                        break
                    dt = time.perf_counter() - t0
                    tv = marginal_total_variation(target, draws)
                    row = {
                        "target": name,
                        "budget": budget,
                        "method": method,
                        "seed": seed,
                        "evaluations": used,
                        "mmtv": float(tv.mean()),
                        "tv": tv.tolist(),
                        "seconds": dt,
                        "verdict": verdict,
                    }
                    rows.append(row)
                    print(
                        f"{name:24s} {budget:6d} {method:12s} {seed:4d} {used:5d} "
                        f"{tv.mean():7.4f} {dt:7.1f}  {verdict or ''}",
                        flush=True,
                    )
                    if args.out:
                        with open(args.out, "w", encoding="utf-8") as fh:
                            json.dump(rows, fh, indent=1)
    print()
    print("\n".join(summarize_rows(rows, args.methods)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
