"""Goals: what a run of a system must achieve, as conditions over its metrics (`[goals]`).

    [goals]
    placed = ">= 18"          # the [sweep] metrics hook's `placed`
    violations = "== 0"       # counted in every run, with or without a hook
    until = 150               # (optional) the virtual seconds of run the goals are stated for

A goal is a metric, a comparison (>=, <=, ==, !=, >, <) and a number: parsed here, never
evaluated as Python. `iotad run --virtual` says whether each held; `iotad stress` runs a system
under the policies its windows allow and reports the goals that fail (docs/stress.md).
"""
from __future__ import annotations

import math
import operator
import re
from dataclasses import dataclass
from typing import Any, Callable, Mapping

# metrics every run has, whatever its hook: the violation events its engine recorded
BUILTIN = ("violations",)
UNTIL = "until"  # not a metric: how long a run the goals are stated for (`iotad stress`'s default --until)
_OPERATORS: dict[str, Callable[[Any, Any], bool]] = {
    ">=": operator.ge, "<=": operator.le, "==": operator.eq, "!=": operator.ne, ">": operator.gt, "<": operator.lt}
_CONDITION = re.compile(r"^\s*(>=|<=|==|!=|>|<)\s*([-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?)\s*$")
_METRIC = re.compile(r"^[A-Za-z_]\w*$")


@dataclass(frozen=True)
class Goal:
    metric: str
    op: str
    bound: float

    def __str__(self) -> str:
        return f"{self.metric} {self.op} {self.bound:g}"

    def held(self, metrics: Mapping[str, Any]) -> bool | None:
        """Whether the run's `metrics` meet it; None when the run has no such number."""
        value = metrics.get(self.metric)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
            return None
        return _OPERATORS[self.op](value, self.bound)


@dataclass(frozen=True)
class Verdict:
    goal: Goal
    value: Any        # the metric's value in the run (None: not measured)
    held: bool | None  # None: not measured, which is a miss

    @property
    def met(self) -> bool:
        return self.held is True

    def line(self) -> str:
        if self.held is None:
            return f"{self.goal}: NOT MEASURED (the run has no metric {self.goal.metric!r})"
        return f"{self.goal}: {'held' if self.held else 'MISSED'} ({self.value:g})" \
            if isinstance(self.value, (int, float)) else f"{self.goal}: {'held' if self.held else 'MISSED'}"


class GoalError(ValueError):
    """A goal that does not parse: one line naming it."""


def parse_goal(metric: Any, condition: Any) -> Goal:
    """`placed = ">= 18"` as a `Goal`; `GoalError` naming it otherwise."""
    if not isinstance(metric, str) or not _METRIC.match(metric):
        raise GoalError(f"[goals] {metric!r}: a goal's key is a metric's name (letters, digits, _)")
    match = _CONDITION.match(condition) if isinstance(condition, str) else None
    bound = float(match.group(2)) if match else math.nan
    if not match or not math.isfinite(bound):
        raise GoalError(f"[goals] {metric} = {_written(condition)}: not a condition; write a comparison "
                        f"(>=, <=, ==, !=, >, <) and a number, e.g. {metric} = \">= 18\"")
    return Goal(metric, match.group(1), bound)


def parse_goals(raw: Any) -> tuple[list[Goal], float | None, list[str]]:
    """The goals of a `[goals]` table, its `until` (None: not given), and one error line per
    entry that does not parse."""
    if not isinstance(raw, dict):
        return [], None, ["[goals]: must be a table of metric = \"condition\", e.g. placed = \">= 18\""]
    goals, errors, until = [], [], None
    for metric, condition in raw.items():
        if metric == UNTIL:
            if isinstance(condition, (int, float)) and not isinstance(condition, bool) \
                    and 0 < condition < math.inf:
                until = float(condition)
            else:
                errors.append(f"[goals] until = {_written(condition)}: the virtual seconds of a run the goals "
                              "are stated for, a number > 0")
            continue
        try:
            goals.append(parse_goal(metric, condition))
        except GoalError as exc:
            errors.append(str(exc))
    return goals, until, errors


def judge(goals: list[Goal], metrics: Mapping[str, Any]) -> list[Verdict]:
    return [Verdict(goal, metrics.get(goal.metric), goal.held(metrics)) for goal in goals]


def all_met(verdicts: list[Verdict]) -> bool:
    return all(verdict.met for verdict in verdicts)


def _written(value: Any) -> str:
    return f"\"{value}\"" if isinstance(value, str) else repr(value)
