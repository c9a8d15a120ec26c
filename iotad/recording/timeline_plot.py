"""A timeline of motor arbitration from a recording: who held the motors, the acks, the violations,
and the delivery problems `iotad check` finds (lost, altered, duplicated, unexplained; late with a
threshold).

The scheduler node is the one whose trace has `schedule` firings (or the one named). A requester
holds the motors from its `schedule[i]` firing until its `commit[i]`, or until another request
is scheduled over it (pre-emption: an ABORT follows). Requester names come from the bindings in
the stored system file (`vision.req -> scheduler.req[0]`), else `req[i]`.
"""
from __future__ import annotations

from pathlib import Path

from iotad.recording.mcap_format import RecordingError
from iotad.recording.mcap_reader import Recording
from iotad.recording.recorded_system import recorded_bindings

ACK_STYLE = {"COMMIT": ("o", "#2a9d3f"), "ABORT": ("v", "#e08a00"), "REJECT": ("X", "#c62828")}


def requester_names(recording: Recording, scheduler: str) -> dict[int, str]:
    """index -> requester name, from the bindings of the recorded system (`[[bind]]` of its
    system.toml, or an in-process run's system.json) into a member of the scheduler's family."""
    leaf = scheduler.split("/")[-1]
    return {target.index: source.node.split("/")[-1] for source, target in recorded_bindings(recording)
            if target.index is not None and target.node.split("/")[-1] == leaf}


def schedulers(recording: Recording) -> dict[str, int]:
    """The nodes that fired `schedule`, with how often, most first."""
    counts = {node: sum(1 for e in recording.trace(node) if e.get("action") == "schedule") for node in recording.nodes()}
    return dict(sorted(((n, c) for n, c in counts.items() if c), key=lambda item: -item[1]))


def find_scheduler(recording: Recording, named: str | None = None) -> str:
    """The node to draw: `named` if it schedules, else the one with the most `schedule` firings."""
    found = schedulers(recording)
    if named is not None and named not in found:
        raise RecordingError(f"{named} never fired 'schedule': it is no motion scheduler "
                             f"(here: {', '.join(found) or 'none'})")
    if not found:
        raise RecordingError("no node fired 'schedule' in this recording: there is no motion scheduler's "
                             f"timeline to draw (nodes: {', '.join(recording.nodes()) or 'none'})")
    return named or next(iter(found))


def timeline(recording: Recording, scheduler: str) -> dict:
    events = recording.trace(scheduler)
    holds, acks, requests = [], [], []
    holder, since = None, None
    end = max((float(e["t"]) for e in events), default=0.0)
    for event in events:
        t, action, index, kind = float(event["t"]), event.get("action"), event.get("index"), event.get("kind")
        index = 0 if index is None else index  # a scheduler of one requester: plain req, ack channels
        if action == "schedule" and kind == "internal":
            if holder is not None:
                holds.append((holder, since, t, "pre-empted"))
            holder, since = index, t
        elif action == "commit" and kind == "internal" and index == holder:
            holds.append((holder, since, t, "committed"))
            holder = None
        elif action == "ack" and kind == "output":
            acks.append((index, t, event.get("value")))
        elif action == "req" and kind == "input":
            requests.append((index, t))
    if holder is not None:
        holds.append((holder, since, end, "holding"))
    violations = [(e["node"], float(e["t"]), (e.get("value") or {}).get("violation", "?"), e.get("action"))
                  for e in recording.violations()]
    return {"holds": holds, "acks": acks, "requests": requests, "violations": violations, "end": end}


MARK_STYLE = {"lost": ("X", "#222222"), "altered": ("D", "#ad1457"), "duplicated": ("P", "#1565c0"),
              "unexplained": ("*", "#7b1fa2"), "reordered": ("s", "#6d4c41"), "causality": ("s", "#6d4c41"),
              "late": ("^", "#e08a00")}


def delivery_marks(recording: Recording, late: float | None = None) -> list[tuple[float, str, str]]:
    """(t, code, text) of every delivery problem (lost, altered, duplicated, unexplained, out of
    order) and, with `late` (seconds), of every delivery slower than that: `iotad check`'s
    cross-check of senders, wire and receivers (docs/checking.md)."""
    from iotad.recording.delivery import check_delivery, problem_marks
    from iotad.recording.replay import default_tolerance

    report = check_delivery(recording, tolerance=default_tolerance(recording))
    return problem_marks(report, late) if report.checked else []


def plot(recording: Recording, output: str | Path, scheduler: str | None = None, title: str | None = None,
         late: float | None = None) -> Path:
    """The timeline; a `delivery` row marks lost, altered, duplicated or unexplained messages when
    there are any, and with `late` (seconds) deliveries slower than that."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    scheduler = find_scheduler(recording, scheduler)
    data = timeline(recording, scheduler)
    names = requester_names(recording, scheduler)
    indexes = sorted({h[0] for h in data["holds"]} | {a[0] for a in data["acks"]} | {r[0] for r in data["requests"]}
                     | set(names))
    rows = {index: k for k, index in enumerate(indexes)}
    violation_row = len(indexes)
    marks = delivery_marks(recording, late)
    delivery_row = violation_row + 1 if marks else None
    rows_drawn = len(indexes) + (2 if marks else 1)
    fig, ax = plt.subplots(figsize=(11, 1.2 + 0.8 * rows_drawn))
    palette = plt.get_cmap("tab10")
    for index, start, stop, how in data["holds"]:
        y = rows[index]
        ax.barh(y, max(stop - start, 1e-3), left=start, height=0.5, color=palette(index % 10), alpha=0.55,
                edgecolor="black", linewidth=0.6, hatch="//" if how == "pre-empted" else None)
    for index, t in data["requests"]:
        ax.plot([t, t], [rows[index] - 0.32, rows[index] + 0.32], color="0.3", linewidth=1.2)
    for index, t, value in data["acks"]:
        marker, color = ACK_STYLE.get(value if isinstance(value, str) else None, ("s", "0.4"))  # struct acks too
        ax.plot(t, rows[index] + 0.42, marker=marker, color=color, markersize=9, markeredgecolor="black",
                markeredgewidth=0.5, linestyle="none")
    codes: dict[str, int] = {}
    for node, t, code, action in data["violations"]:
        codes[code] = codes.get(code, 0) + 1
        ax.plot(t, violation_row, marker="|", color="#c62828", markersize=18, markeredgewidth=2)
        if len(data["violations"]) <= 4:  # few: name each; many: the summary below says what they are
            ax.annotate(f"{node}.{action}: {code}", (t, violation_row), xytext=(3, -12),
                        textcoords="offset points", fontsize=7, color="#c62828")
    if codes:
        summary = ", ".join(f"{code} x{n}" for code, n in sorted(codes.items()))
        ax.annotate(summary, (1.0, 0.02), xycoords="axes fraction", ha="right", va="bottom", fontsize=8,
                    color="#c62828")
    kinds: dict[str, int] = {}
    for k, (t, code, text) in enumerate(marks):
        kinds[code] = kinds.get(code, 0) + 1
        marker, color = MARK_STYLE.get(code, ("o", "0.3"))
        ax.plot(t, delivery_row, marker=marker, color=color, markersize=9, markeredgecolor="black",
                markeredgewidth=0.4, linestyle="none")
        if len(marks) <= 4:
            right = t > 0.75 * max(data["end"], 1e-3)  # near the right edge: the text goes left
            ax.annotate(text, (t, delivery_row), xytext=(-4 if right else 4, 10 if k % 2 == 0 else -16),
                        textcoords="offset points", fontsize=7, color=color, ha="right" if right else "left")
    labels = [f"{names.get(i, f'req[{i}]')}  (req[{i}])" if i in names else f"req[{i}]" for i in indexes]
    ticks = list(range(len(indexes))) + [violation_row]
    labels.append(f"violations ({len(data['violations'])})")
    if marks:
        ticks.append(delivery_row)
        labels.append("delivery: " + ", ".join(f"{code} {n}" for code, n in sorted(kinds.items())))
    ax.set_yticks(ticks, labels)
    ax.set_ylim(-0.7, ticks[-1] + 0.8)
    ax.invert_yaxis()
    ax.set_xlim(0, max(data["end"], 1e-3) * 1.02)
    ax.set_xlabel("time (node clock, spec units)")
    ax.grid(axis="x", alpha=0.3)
    system = recording.system or ""
    ax.set_title(title or f"{system}: who held the motors ({scheduler})", fontsize=11,
                 parse_math=False)  # a title is text: "$5" is not mathtext
    legend = [Patch(facecolor="0.7", edgecolor="black", label="holds the motors"),
              Patch(facecolor="0.7", edgecolor="black", hatch="//", label="held, then pre-empted"),
              Line2D([], [], color="0.3", label="request"),
              *[Line2D([], [], marker=m, color=c, linestyle="none", markeredgecolor="black", label=f"ack {v}")
                for v, (m, c) in ACK_STYLE.items()],
              Line2D([], [], marker="|", color="#c62828", linestyle="none", markersize=12, label="violation"),
              *[Line2D([], [], marker=MARK_STYLE[code][0], color=MARK_STYLE[code][1], linestyle="none",
                       markeredgecolor="black", label=code) for code in sorted({c for _, c, _ in marks})
                if code in MARK_STYLE]]
    ax.legend(handles=legend, loc="upper center", bbox_to_anchor=(0.5, -0.32 if len(indexes) < 3 else -0.2),
              ncol=7, fontsize=8, frameon=False)
    fig.tight_layout()
    output = Path(output)
    fig.savefig(output, dpi=110)
    plt.close(fig)
    return output
