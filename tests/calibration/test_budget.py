"""The minimum budget: what q and the loop settings need, and the refusal's words."""

from __future__ import annotations

from pathlib import Path

from susp_bo.calibration.budget import budget_message, budget_requirement, budget_too_small


def test_budget_minimum_follows_the_loop_structure() -> None:
    # q = 7 with the loop's defaults: a design of 35, one batch of 4, 8 check points
    loop = budget_requirement(7, None, 4, 8)
    assert (loop.design, loop.minimum) == (35, 47)
    # the command line's defaults (design 40, batches of 8, 8 check points): 40 is the design
    cli = budget_requirement(7, 40, 8, 8)
    assert cli.minimum == 56 and "q = 7" in cli.describe()
    reason = budget_too_small(40, cli)
    assert reason is not None and reason["minimum"] == 56 and "40" in reason["message"]
    assert budget_too_small(56, cli) is None
    # a configured design smaller than q needs does not lower the minimum, and the words
    # say that the smaller design is what runs (the loop honours a configured size)
    small = budget_requirement(7, 3, 8, 8)
    assert small.minimum == 51
    assert (
        "the configured design of 3 points, which the run uses, is smaller than the 35 that "
        "q = 7 needs" in small.describe()
    )
    assert "configured" not in cli.describe() and "configured" not in loop.describe()


def test_a_design_smaller_than_q_needs_is_named_as_the_one_that_runs(tmp_path: Path) -> None:
    """q = 9 with the config's design of 40: the refusal named "a design of 45" (5 q) while the
    run spent 40 (outside probe, session 30). The design stays the config's, with or without
    --budget (a study resumed with --resume --budget must replay its design), and the words
    say that 40 runs."""
    from susp_bo.calibration.budget import calibrated_count, design_for_budget
    from susp_bo.rig.catalog import rig_path
    from susp_bo.study_config import StudyConfig

    rig = tmp_path / "nine.toml"  # the shipped rig with two per-side yaw dampers: q = 9
    extra = "".join(
        f"""
[[calibration.parameters]]
name = "yaw_damper_damping@{side}"
lower = 0.5e6
upper = 8.0e6
unit = "N·s/m"
"""
        for side in ("bogie_front_left", "bogie_front_right")
    )
    rig.write_text(rig_path("hst_trailer").read_text(encoding="utf-8") + extra, encoding="utf-8")
    config = StudyConfig(rig=str(rig), data=Path("."), out=Path("out"))
    assert calibrated_count(config) == 9 and config.budget.initial_design == 40
    design = design_for_budget(config, 200)
    assert design == 40  # the config's, as without --budget
    b = config.budget
    requirement = budget_requirement(9, design, b.batch_size, b.check_points)
    assert requirement.minimum == 45 + b.batch_size + b.check_points
    assert (
        "the configured design of 40 points, which the run uses, is smaller than the 45 that "
        "q = 9 needs" in requirement.describe()
    )
    seven = StudyConfig(rig="hst_trailer", data=Path("."), out=Path("out"))
    assert design_for_budget(seven, 200) == 40  # the demo's q = 7: unchanged
    assert design_for_budget(seven, 52) == 36 and design_for_budget(seven, 40) == 35


def test_the_refusal_names_the_flag_the_value_the_minimum_and_the_override() -> None:
    requirement = budget_requirement(7, 40, 8, 8)
    message = budget_message(40, requirement, flag="budget", override="set allow_small_budget")
    assert message.startswith("budget 40 is below the minimum 56 for q = 7 parameters")
    assert "give budget 56 or more" in message and "set allow_small_budget" in message
    assert "--budget" not in message
