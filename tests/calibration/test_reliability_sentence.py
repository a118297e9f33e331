"""The verdict's sentence: why it is trusted (naming the sampler), or the first reason
with its advice and the other reasons' codes."""

from __future__ import annotations

from susp_bo.calibration.reliability_sentence import sentence


def test_trusted_sentence_names_hmc_when_its_draws_were_assessed() -> None:
    evidence = {"optimum_gap_nats": 0.4, "check_points": 8, "r_hat_max": 1.012, "ess_min": 900}
    walk = sentence((), {**evidence, "sampler": "random_walk"}, "command_line")
    hmc = sentence((), {**evidence, "sampler": "hmc"}, "command_line")
    assert walk.startswith("Trusted: the search converged (best log L 0.40 nats below")
    assert "the MCMC mixed (R-hat <= 1.012, ESS >= 900)" in walk
    assert "the MCMC mixed (HMC, R-hat <= 1.012, ESS >= 900)" in hmc
    above = sentence((), {**evidence, "optimum_gap_nats": -0.02}, "python")
    assert "best log L 0.02 nats above the surrogate's predicted maximum)" in above
    for tiny in (0.004, -0.001, 0.0):  # "0.00 nats above" had a side it could not show
        level = sentence((), {**evidence, "optimum_gap_nats": tiny}, "python")
        assert "(best log L at the surrogate's predicted maximum (within 0.005 nats))" in level


def test_not_trusted_sentence_gives_the_first_reason_its_advice_and_the_others() -> None:
    reasons = (
        {"code": "poor_mixing", "message": "the MCMC did not mix: R-hat 1.3 > 1.05 on a"},
        {"code": "multimodal", "message": "m"},
    )
    text = sentence(reasons, {"budget": 60, "minimum_budget": 51}, "command_line")
    assert text == (
        "Not trusted: the MCMC did not mix: R-hat 1.3 > 1.05 on a (also: multimodal); "
        "rerun with more MCMC draws ([mcmc] draws, chains)."
    )
    small = sentence(
        ({"code": "budget_too_small", "message": "b"},),
        {"budget": 40, "minimum_budget": 51},
        "command_line",
    )
    assert small == (  # --resume: a plain rerun into the folder is refused (it holds a study)
        "Not trusted: b; rerun with --resume --budget 51 or more (the evaluations already "
        "made are reused)."
    )


def test_a_python_caller_is_told_the_settings_not_the_flags() -> None:
    """Sentences from calibrate() told a Python caller to "rerun with --resume --budget 400"
    or to set "[mcmc] draws", which do not exist there (outside probe, session 24)."""
    reasons = ({"code": "not_converged", "message": "m"}, {"code": "poor_mixing", "message": "p"})
    evidence = {"budget": 200, "minimum_budget": 22}
    python = sentence(reasons, evidence, "python")
    assert python == (
        "Not trusted: m (also: poor_mixing); rerun with a larger budget, "
        "CalibrationSettings(max_evaluations=400)."
    )
    assert "--" not in python
    assert "--resume --budget 400" in sentence(reasons, evidence, "command_line")
    mixing = sentence(reasons[1:], evidence, "python")
    assert "CalibrationSettings(mcmc_samples=..., mcmc_chains=...)" in mixing
    small = sentence(({"code": "budget_too_small", "message": "b"},), evidence, "python")
    assert small.endswith("give CalibrationSettings(max_evaluations=22) or more.")


def test_a_verdict_is_reworded_for_a_study_without_changing_anything_else() -> None:
    from susp_bo.calibration.reliability import Reliability

    reasons = ({"code": "surrogate_misfit", "message": "m"},)
    evidence = {"budget": 60, "minimum_budget": 51}
    python = Reliability("not_trusted", reasons, sentence(reasons, evidence, "python"), evidence)
    study = python.worded_for("command_line")
    assert study.sentence.endswith("rerun with --resume --budget 120.")
    assert (study.verdict, study.reasons, study.evidence) == (
        python.verdict,
        python.reasons,
        python.evidence,
    )


def test_a_posterior_too_narrow_for_a_global_surrogate_is_told_the_trust_region() -> None:
    """A posterior 1e-4 of C_w wide came out exact but `not_converged`, advised "more
    budget", where trust_region=True gives it `trusted` in 30 evaluations (outside probe,
    session 24, F4)."""
    narrow = {"code": "not_converged", "message": "m", "posterior_width": 2e-4}
    evidence = {"budget": 200, "minimum_budget": 22}
    python = sentence((narrow,), evidence, "python")
    assert "CalibrationSettings(trust_region=True) refines in a box that follows it" in python
    assert python.endswith(
        "or rerun with a larger budget, CalibrationSettings(max_evaluations=400)."
    )
    assert sentence((narrow,), evidence, "command_line").endswith("--resume --budget 400.")
    plain = {"code": "not_converged", "message": "m"}
    assert "trust_region" not in sentence((plain,), evidence, "python")


def test_scattered_failures_lead_the_advice_whichever_reason_comes_first() -> None:
    """Failures that strike anywhere poison the surrogate with stand-in values: more budget
    (the first reason's advice) cannot fix that, nor can narrower bounds."""
    reasons = (
        {"code": "not_converged", "message": "m"},
        {"code": "failed_region", "message": "f", "scattered": True},
    )
    line = sentence(reasons, {"budget": 200}, "command_line")
    assert line.endswith(
        "make the failing simulations run (the log and evaluations.sqlite name them; "
        "narrowing the admissible interval will not avoid failures that strike anywhere), "
        "then rerun."
    )
    assert "make the failing evaluations run (result.X where result.y is NaN" in sentence(
        reasons, {"budget": 200}, advice_for="python"
    )
    region = ({"code": "failed_region", "message": "f"},)
    assert "narrow the admissible interval" in sentence(region, {"budget": 200}, "command_line")


def test_mass_left_outside_the_box_is_not_told_to_add_budget() -> None:
    """Review, session 25: more budget refines the same box; the advice says where to look
    (command line) or to search all of C_w (Python)."""
    face = ({"code": "search_box_edge", "message": "m"},)
    left = ({"code": "search_box_edge", "message": "m", "evaluations_outside_box": 2},)
    assert sentence(face, {"budget": 200}, "command_line").endswith(
        "rerun with --resume --budget 400."
    )
    line = sentence(left, {"budget": 200}, "command_line")
    assert "look at the evaluations outside the search box" in line and "--budget" not in line
    assert "CalibrationSettings(trust_region=False)" in sentence(left, {"budget": 200}, "python")


def test_forced_hmc_that_did_not_mix_is_told_to_use_auto_not_more_draws() -> None:
    """Outside probe, session 25: mcmc_sampler="hmc" on modes 10 sd apart was told to draw
    more, which cannot help HMC cross the gap."""
    reasons = ({"code": "poor_mixing", "message": "m"},)
    line = sentence(reasons, {"budget": 200, "sampler": "hmc"}, "python")
    assert 'CalibrationSettings(mcmc_sampler="auto")' in line
    assert "mcmc_samples" in sentence(reasons, {"budget": 200, "sampler": "random_walk"}, "python")


def test_a_trusted_sentence_says_when_the_mass_outside_its_box_is_unknown() -> None:
    """Session 28: the box-mass rule is silent (null) on sharp posteriors — demo seed 4, 12
    of 20 monitoring campaigns — and the trusted sentence did not say so."""
    evidence = {"optimum_gap_nats": 0.01, "check_points": 8, "r_hat_max": 1.01, "ess_min": 900}
    caveat = "the posterior mass outside the search box could not be estimated"
    unknown = sentence((), {**evidence, "mass_outside_box": None}, "command_line")
    assert unknown.startswith("Trusted: the search converged")
    assert caveat in unknown and "neither seen nor ruled out" in unknown
    assert unknown.endswith("ruled out.")
    for known in ({**evidence, "mass_outside_box": 1e-30}, evidence):  # estimated; no box
        text = sentence((), known, "command_line")
        assert caveat not in text and text.endswith("ESS >= 900).")


def test_a_trusted_sentence_says_when_the_lack_of_fit_was_not_checked() -> None:
    """Session 32: with one measured run (or spectra that failed) F is null, and the trusted
    sentence said nothing of the check it could not make; both caveats read as one sentence."""
    evidence = {"optimum_gap_nats": 0.01, "check_points": 8, "r_hat_max": 1.01, "ess_min": 900}
    caveat = "the lack of fit between measured runs could not be checked"
    alone = sentence((), {**evidence, "lack_of_fit_ratio": None}, "python")
    assert alone.startswith("Trusted: the search converged") and caveat in alone
    assert alone.endswith("neither seen nor ruled out.") and alone.count("; but ") == 1
    both = sentence(
        (), {**evidence, "lack_of_fit_ratio": None, "mass_outside_box": None}, "command_line"
    )
    assert both.count("; but ") == 1 and "; and the lack of fit" in both
    assert "mass_outside_box null" in both and both.endswith("ruled out.")
    for checked in ({**evidence, "lack_of_fit_ratio": 1.1}, evidence):  # computed; no spectra
        assert caveat not in sentence((), checked, "python")
    refused = ({"code": "poor_mixing", "message": "m"},)
    assert caveat not in sentence(refused, {**evidence, "lack_of_fit_ratio": None}, "python")
