"""A sweep's summary picture: one panel per metric and swept parameter, the metric against the
parameter, a line for each value of the other swept parameters, each point the mean over the
seeds with their spread (lowest to highest) as a bar, and every seed's run as a faint dot."""
from __future__ import annotations

from pathlib import Path
from statistics import fmean

COLOURS = ("#3a6ea5", "#c62828", "#2a9d3f", "#e08a00", "#8e44ad", "#00838f", "#6d4c41", "#ad1457")
MOST_LINES = len(COLOURS)  # past that, the other parameters' values are pooled into one line


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def metrics_of(rows: list[dict], params: list[str]) -> list[str]:
    """The numeric metrics of the table's ok rows, in column order."""
    fixed = {"run", "seed", "policy", "status", "error", *params}
    names: list[str] = []
    for row in rows:
        names += [name for name in row if name not in fixed and name not in names]
    ok = [row for row in rows if row.get("status") == "ok"]
    return [name for name in names if any(_number(row.get(name)) for row in ok)]


def plot_summary(rows: list[dict], params: list[str], output: str | Path, title: str) -> Path | None:
    """Draw the summary of `rows` (a sweep's table) to `output`; None when there is nothing to
    draw (no swept parameter, no ok run or no numeric metric)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [row for row in rows if row.get("status") == "ok"]
    metrics = metrics_of(rows, params)
    if not params or not ok or not metrics:
        return None
    failed = len(rows) - len(ok)
    height = 2.1 * len(metrics) + 1.0
    fig, axes = plt.subplots(len(metrics), len(params), squeeze=False, figsize=(4.2 * len(params) + 1.2, height),
                             sharex="col")
    for column, param in enumerate(params):
        xs = sorted({row[param] for row in ok}, key=lambda v: (not _number(v), v if _number(v) else str(v)))
        numeric = all(_number(x) for x in xs)
        position = {x: (x if numeric else k) for k, x in enumerate(xs)}
        span = (max(xs) - min(xs) if numeric and len(xs) > 1 else 1.0) or 1.0
        others = [p for p in params if p != param]
        groups = sorted({tuple(row[p] for p in others) for row in ok}, key=str)
        if len(groups) > MOST_LINES:
            groups = [None]
        for line, group in enumerate(groups):
            members = [row for row in ok if group is None or tuple(row[p] for p in others) == group]
            label = "all runs" if group is None or not others else \
                ", ".join(f"{p.split('.')[-1]}={_short(v)}" for p, v in zip(others, group))
            colour = COLOURS[line % len(COLOURS)]
            shift = (line - (len(groups) - 1) / 2) * 0.012 * span  # lines side by side, their bars apart
            for row_index, metric in enumerate(metrics):
                ax = axes[row_index][column]
                at, means, low, high = [], [], [], []
                for x in xs:
                    values = [row[metric] for row in members if row[param] == x and _number(row.get(metric))]
                    if not values:
                        continue
                    mean = fmean(values)
                    at.append(position[x] + shift)
                    means.append(mean)
                    low.append(mean - min(values))
                    high.append(max(values) - mean)
                    ax.scatter([position[x] + shift] * len(values), values, color=colour, alpha=0.4, s=14,
                               linewidths=0)
                if at:
                    ax.errorbar(at, means, yerr=[low, high], color=colour, marker="o", markersize=4, capsize=3,
                                linewidth=1.4, label=label if row_index == 0 else None)
        for row_index, metric in enumerate(metrics):
            ax = axes[row_index][column]
            ax.grid(alpha=0.3)
            if not numeric:
                ax.set_xticks(range(len(xs)), [_short(x) for x in xs])
            elif len(xs) <= 8:  # a few values: a tick at each, none between
                ax.set_xticks(xs, [_short(x) for x in xs])
            if row_index == len(metrics) - 1:
                ax.set_xlabel(param)
            if column == 0:
                ax.set_ylabel(_label(metric), fontsize=9)
        if len(groups) > 1 or (groups and groups[0] is not None and others):
            axes[0][column].legend(fontsize=7, loc="best")
    seeds = len({row.get("seed") for row in ok})
    note = f"{len(ok)} runs, {seeds} seeds each point (bar: lowest to highest; dots: each run)" + \
        (f"; {failed} failed runs left out" if failed else "")
    fig.suptitle(f"{title}\n{note}", fontsize=11, parse_math=False)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.55 / height))  # room for the two lines of the title
    path = Path(output)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _label(metric: str) -> str:
    """`wander_s` -> "wander (s)": a metric's unit is its name's last word."""
    name, _, unit = metric.rpartition("_")
    return f"{name.replace('_', ' ')} ({unit})" if name and unit in ("s", "m", "ms", "rad") else metric.replace("_", " ")


def _short(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)
