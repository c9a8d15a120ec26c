"""A stress run's picture: one panel per goal, the goal's metric in each run (eager, latest,
then the random seeds), a dot green where the goal held and red where it was missed, and the
goal's bound as a dashed line."""
from __future__ import annotations

from pathlib import Path

HELD, MISSED, BOUND = "#2a9d3f", "#c62828", "#555555"


def plot_stress(results: list, goals: list, output: str | Path, title: str) -> Path | None:
    """Draw `results` (stress_runs.RunResult, plan order) against `goals` to `output`; None when
    there is nothing to draw (no goal, or no run that finished)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [result for result in results if result.status == "ok"]
    if not goals or not ok:
        return None
    labels = [result.policy.replace("random:", "r") for result in ok]
    fig, axes = plt.subplots(len(goals), 1, squeeze=False, figsize=(max(6.0, 0.38 * len(ok) + 2.0), 2.2 * len(goals) + 0.8))
    for axis, goal in zip(axes[:, 0], goals):
        for x, result in enumerate(ok):
            value = result.metrics.get(goal.metric)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                held = goal.held(result.metrics)
                axis.plot(x, value, "o", color=HELD if held else MISSED, markersize=6)
        axis.axhline(goal.bound, color=BOUND, linestyle="--", linewidth=1)
        axis.set_ylabel(goal.metric)
        axis.set_title(str(goal), fontsize=9, loc="left")
        axis.set_xticks(range(len(ok)))
        axis.set_xticklabels(labels, rotation=60, fontsize=7)
        axis.grid(axis="y", alpha=0.3)
    failed = len(results) - len(ok)
    fig.suptitle(title + (f" ({failed} run{'s' if failed != 1 else ''} failed, not drawn)" if failed else ""), fontsize=10)
    fig.tight_layout()
    output = Path(output)
    fig.savefig(output, dpi=90)
    plt.close(fig)
    return output
