"""How a stage stands after an iteration, as one typed outcome: it goes on, it is promoted,
it has spent its budget, or it fails (its budget spent unpromoted with ``if_not_promoted:
fail``). ``learner.curriculum.CurriculumState.verdict`` decides from the rules' figures, and
``learner.evaluation.training_hooks.StageJudging.decide`` adds the stage's evaluation, its
confirmation and the network the stage ends with; everything after (reports, checkpoints,
recordings, the next stage) reads the verdict and never changes it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import Enum
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from gaitforge.learner.policy import ActorCritic
    from gaitforge.learner.stage_spec import PromotionRule

PROMOTED_PREFIX = "promoted: "
"""how the text of a promotion starts"""
BUDGET_SPENT_TEXT = "budget spent"
"""the text of a stage that spent its budget (failed or not: the shortfall names the rules)"""


class Outcome(Enum):
    """Where a stage is after an iteration."""

    GOES_ON = "goes on"
    PROMOTED = "promoted"
    BUDGET_SPENT = "budget spent"
    FAILED = "failed"


@dataclass(frozen=True)
class RuleFigure:
    """A promotion rule and the figure it was judged on (a training window's mean, or the
    evaluation's)."""

    rule: PromotionRule
    figure: float

    @property
    def passed(self) -> bool:
        return self.rule.passes(self.figure)

    def __str__(self) -> str:
        return f"{self.rule.metric} {self.figure:.3g} {self.rule.op} {self.rule.value:g}"


@dataclass(frozen=True)
class KeptNetwork:
    """The best network a ``keep_best`` stage evaluated, which it ends with in place of its
    last: the network, the run's env steps when it was kept and its evaluation (``eval_*``)."""

    network: ActorCritic
    env_steps: int
    evaluation: dict[str, float]


@dataclass(frozen=True)
class StageVerdict:
    """The stage's outcome after an iteration, with what it was decided on.

    ``figures`` are the promotion rules' figures where every rule could be judged (empty
    otherwise); ``evaluation`` and ``confirmation`` the deterministic evaluations run at this
    iteration (``eval_*`` metrics; None where none ran), ``confirmed`` the rules' figures on
    the confirmation of a promotion; ``kept`` the network the stage ends with where it is
    not its last; ``shortfall`` says, for a failed stage, each rule and how far it fell short.
    """

    outcome: Outcome
    figures: tuple[RuleFigure, ...] = ()
    evaluation: dict[str, float] | None = None
    confirmation: dict[str, float] | None = None
    confirmed: tuple[RuleFigure, ...] = ()
    kept: KeptNetwork | None = None
    shortfall: str | None = None

    @property
    def ends(self) -> bool:
        """The stage is over after this iteration."""
        return self.outcome is not Outcome.GOES_ON

    @property
    def promoted(self) -> bool:
        return self.outcome is Outcome.PROMOTED

    @property
    def text(self) -> str | None:
        """Why the stage ends, as the iteration's metrics and the displays report it
        (``"promoted: speed 1.2 >= 1, ...; confirmed: ..."``, ``"budget spent"``); None while
        it goes on."""
        if self.outcome is Outcome.GOES_ON:
            return None
        if self.outcome is not Outcome.PROMOTED:
            return BUDGET_SPENT_TEXT
        text = PROMOTED_PREFIX + ", ".join(str(figure) for figure in self.figures)
        if self.confirmed:
            text += "; confirmed: " + ", ".join(str(figure) for figure in self.confirmed)
        return text

    def failed(self, shortfall: str) -> StageVerdict:
        """This verdict (its budget spent) as a failure, ``shortfall`` saying why."""
        assert self.outcome is Outcome.BUDGET_SPENT
        return replace(self, outcome=Outcome.FAILED, shortfall=shortfall)

    def ended_with(self) -> dict[str, float]:
        """The ``eval_*`` metrics of the network the stage ends with: the kept network's,
        else this iteration's evaluation (empty without one)."""
        if self.kept is not None:
            return self.kept.evaluation
        return dict(self.evaluation or {})


GOES_ON = StageVerdict(Outcome.GOES_ON)
