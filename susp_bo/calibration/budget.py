"""The smallest budget a calibration can be run with: refused below it, named in the refusal.

The loop needs room for its own structure: a space-filling design of max(10, 5 q)
points (or the configured one when larger), one refinement batch and the held-out
check of the surrogate. :func:`budget_requirement` gives that minimum for q
parameters and the loop settings; the loop (:func:`.loop.calibrate`), the study and
the command line refuse a smaller budget before any simulation with
:func:`budget_message` unless explicitly allowed, and the reliability verdict then
carries :func:`budget_too_small` (:mod:`.reliability`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from susp_bo.calibration.design import default_design_size

if TYPE_CHECKING:
    from susp_bo.study_config import StudyConfig


class BudgetTooSmallError(ValueError):
    """The budget leaves no room for refinement and the check (raised before any evaluation)."""


@dataclass(frozen=True)
class BudgetRequirement:
    """The smallest budget the loop's structure needs for q parameters.

    Attributes:
        q: number of calibrated parameters.
        design: design points needed: max(configured design, max(10, 5 q)).
        batch: one refinement batch (``batch_size``).
        check: held-out check points (``check_points``).
        configured: the configured design size (None: the default), which the loop runs
            even when it is smaller than q needs; :meth:`describe` then says so.
    """

    q: int
    design: int
    batch: int
    check: int
    configured: int | None = None

    @property
    def minimum(self) -> int:
        """design + batch + check evaluations."""
        return self.design + self.batch + self.check

    def describe(self) -> str:
        """'56 for q = 7 parameters (a design of 40 + one refinement batch of 8 + ...)'."""
        check = f" + {self.check} check points" if self.check else ""
        smaller = ""
        if self.configured is not None and 0 < self.configured < self.design:
            # the loop runs the configured design; the minimum still counts what q needs
            # (outside probe, session 30: "a design of 45" named where 40 ran)
            smaller = (
                f"; the configured design of {self.configured} points, which the run uses, "
                f"is smaller than the {self.design} that q = {self.q} needs"
            )
        return (
            f"{self.minimum} for q = {self.q} parameters (a design of {self.design}"
            f" + one refinement batch of {self.batch}{check}{smaller})"
        )


def budget_requirement(
    q: int, initial_design: int | None, batch_size: int, check_points: int
) -> BudgetRequirement:
    """The minimum budget for q parameters given the loop settings.

    Args:
        q: number of calibrated parameters.
        initial_design: configured design size (None: the loop's default max(10, 5 q)).
        batch_size: points per refinement batch.
        check_points: held-out check points.
    """
    design = max(int(initial_design or 0), default_design_size(q))
    configured = None if initial_design is None else int(initial_design)
    return BudgetRequirement(int(q), design, int(batch_size), int(check_points), configured)


def budget_message(
    budget: int,
    requirement: BudgetRequirement,
    flag: str = "--budget",
    override: str = "pass --allow-small-budget",
) -> str:
    """The refusal message: names ``flag``, the value, the minimum and the override."""
    return (
        f"{flag} {budget} is below the minimum {requirement.describe()}: no room to refine "
        f"the search and check the surrogate; give {flag} {requirement.minimum} or more, or "
        f"{override} to run anyway (the result is then marked not trusted)"
    )


def budget_too_small(budget: int, requirement: BudgetRequirement) -> dict[str, Any] | None:
    """The reliability reason ``budget_too_small`` (``code``, ``message``, the numbers) when
    ``budget`` < the requirement's minimum, else None."""
    if budget >= requirement.minimum:
        return None
    return {
        "code": "budget_too_small",
        "message": (
            f"the budget of {budget} evaluations is below the minimum {requirement.describe()}"
        ),
        "budget": int(budget),
        "minimum": requirement.minimum,
    }


def calibrated_count(config: StudyConfig) -> int | None:
    """q of the study (None when the rig or the parameter list is bad: the study reports it)."""
    from susp_bo.rig.spec import load_rig_spec

    try:
        return len(config.check_parameters(load_rig_spec(config.rig).calibration_names))
    except (FileNotFoundError, ValueError):
        return None


def design_for_budget(config: StudyConfig, budget: int) -> int:
    """The design size for a budget given on the command line (``--budget`` of
    ``susp-bo calibrate`` and ``susp-bo monitor``): the config's, shrunk when the budget
    is tight.

    It shrinks to leave one refinement batch and the check points, but not below what q
    needs (max(10, 5 q)) — nor above the config's own design, which runs as it does without
    ``--budget`` (at q >= 9 the default 40 is below 5 q; the refusal's words then say so,
    :meth:`BudgetRequirement.describe`, and a resumed study keeps its design) — and never
    beyond the budget: q = 7 with the default design of 40,
    batches of 8 and 8 check points gets 40 from a budget of 56 up, budget − 16 from 51 to
    55, and 35 below (refused unless small budgets are allowed). So the minimum a refusal
    names is the budget that then runs (the design does not grow with the budget given).
    """
    b = config.budget
    q = calibrated_count(config)
    room = budget - b.batch_size - b.check_points
    floor = default_design_size(q) if q is not None else 2
    return max(2, min(b.initial_design, max(room, floor), budget))
