"""The minimum budget: what q and the loop settings need, and the refusal's words."""

from __future__ import annotations

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
    # a configured design smaller than q needs does not lower the minimum
    assert budget_requirement(7, 3, 8, 8).minimum == 51


def test_the_refusal_names_the_flag_the_value_the_minimum_and_the_override() -> None:
    requirement = budget_requirement(7, 40, 8, 8)
    message = budget_message(40, requirement, flag="budget", override="set allow_small_budget")
    assert message.startswith("budget 40 is below the minimum 56 for q = 7 parameters")
    assert "give budget 56 or more" in message and "set allow_small_budget" in message
    assert "--budget" not in message
