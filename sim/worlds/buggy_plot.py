"""Buggy's run as the paper's Figures 4 and 5: the arena, the path coloured by the active
behaviour, and hunger and fear over time.

A recording is Buggy's when a node outputs `landmark` and `pose` (the sensors: walls, cracks and
food, then x, y, yaw) and a node outputs `mood` (buggy: hunger, fear, the active behaviour and
the basic behaviour driving: WANDER, FOLLOW, EAT, AVOID). An `estop` input (the motor node's) is
marked on the path and over time: Buggy stops there, whatever its behaviour says. Everything
comes from the nodes' trace events, so a virtual-time run and a real-time run draw the same way.
"""
from __future__ import annotations

from bisect import bisect_right
from pathlib import Path

from iotad.recording.mcap_format import RecordingError
from iotad.recording.mcap_reader import Recording

COLOURS = {"WANDER": "#3a6ea5", "FOLLOW": "#e08a00", "EAT": "#2a9d3f", "AVOID": "#c62828"}
LABELS = {"WANDER": "wander", "FOLLOW": "follow crack", "EAT": "eat", "AVOID": "avoid wall (subconscious)"}


def _outputs(recording: Recording, channel: str) -> dict[str, list[tuple[float, object]]]:
    """node -> [(t, value)] of its `channel` outputs, t in seconds (events count spec units)."""
    out: dict[str, list] = {}
    unit = recording.time_unit
    for event in recording.trace():
        if event.get("kind") == "output" and event.get("action") == channel:
            out.setdefault(event["node"], []).append((float(event["t"]) * unit, event.get("value")))
    return out


def matches(recording: Recording) -> bool:
    channels = {topic.rsplit("/", 1)[-1] for topic in recording.topics()}
    return {"pose", "mood", "landmark"} <= channels


def buggy_data(recording: Recording) -> dict:
    """The arena, the path and the moods of a Buggy recording (RecordingError if it is none)."""
    poses, moods, landmarks = (_outputs(recording, c) for c in ("pose", "mood", "landmark"))
    if not poses or not moods:
        raise RecordingError("not a Buggy recording: no node outputs both 'pose' and 'mood'")
    world = next(iter(poses))
    path = sorted(poses[world], key=lambda p: p[0])
    mood = sorted(next(iter(moods.values())), key=lambda p: p[0])
    arena = {"walls": None, "cracks": [], "food": {}, "eaten": []}
    for t, mark in sorted(next(iter(landmarks.values()), []), key=lambda p: p[0]):
        kind = mark.get("kind")
        if kind == "WALL":
            arena["walls"] = (mark["x1"], mark["y1"], mark["x2"], mark["y2"])
        elif kind == "CRACK":
            crack = ((mark["x1"], mark["x2"]), (mark["y1"], mark["y2"]))
            if crack not in arena["cracks"]:  # a restarted world says its landmarks again
                arena["cracks"].append(crack)
        elif kind == "FOOD":
            arena["food"][mark["id"]] = (mark["x1"], mark["y1"])
        elif kind == "EATEN":
            arena["eaten"].append((t, mark["id"]))
    estops = sorted((float(e["t"]) * recording.time_unit, bool(e.get("value"))) for e in recording.trace()
                    if e.get("kind") == "input" and e.get("action") == "estop")
    restarts = [t * recording.time_unit for t in recording.restart_times(world)]
    return {"path": path, "mood": mood, "arena": arena, "estops": estops, "world": world, "restarts": restarts}


def _runs(path: list, restarts: list[float]) -> list[list]:
    """`path` cut at each restart of the world node: the poses of each of its runs."""
    runs: list[list] = [[]]
    cuts = iter(sorted(restarts))
    cut = next(cuts, float("inf"))
    for t, pose in path:
        while t >= cut:
            runs.append([])
            cut = next(cuts, float("inf"))
        runs[-1].append((t, pose))
    return runs


def _pose_at(path: list, t: float) -> dict | None:
    """The last pose at or before `t` (the first, before the path starts)."""
    if not path:
        return None
    k = bisect_right([p[0] for p in path], t) - 1
    return path[max(k, 0)][1]


def plot(recording: Recording, output: str | Path, title: str | None = None) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle

    data = buggy_data(recording)
    path, mood, arena = data["path"], data["mood"], data["arena"]
    mood_t = [t for t, _ in mood]

    def doing_at(t: float) -> str:
        k = bisect_right(mood_t, t) - 1
        return mood[max(k, 0)][1].get("doing", "WANDER")

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 5.6), gridspec_kw={"width_ratios": [1, 1.25]})
    if arena["walls"]:
        x1, y1, x2, y2 = arena["walls"]
        ax.add_patch(Rectangle((x1, y1), x2 - x1, y2 - y1, fill=False, linewidth=4, edgecolor="0.35"))
        pad = 0.08 * (x2 - x1)
        ax.set_xlim(x1 - pad, x2 + pad)
        ax.set_ylim(y1 - pad, y2 + pad)
    for xs, ys in arena["cracks"]:
        ax.plot(xs, ys, color="#5b3a1e", linewidth=3, solid_capstyle="round", zorder=1)
    for fx, fy in arena["food"].values():
        ax.plot(fx, fy, marker="s", color="#2a9d3f", markersize=8, markeredgecolor="black", zorder=2,
                linestyle="none")
    segments, colours = [], []
    restarts = data["restarts"]
    runs = _runs(path, restarts)  # one list of poses per world
    for run in runs:  # no line from the last pose of a world to the first of the next
        for (t0, a), (t1, b) in zip(run, run[1:]):
            segments.append([(a["x"], a["y"]), (b["x"], b["y"])])
            colours.append(COLOURS.get(doing_at(t1), "0.5"))
    ax.add_collection(LineCollection(segments, colors=colours, linewidths=1.6, zorder=3))
    if path:
        start, end = path[0][1], path[-1][1]
        ax.plot(start["x"], start["y"], marker="o", color="white", markeredgecolor="black", markersize=9, zorder=4)
        ax.plot(end["x"], end["y"], marker="o", color="black", markersize=7, zorder=4)
    for t in restarts:  # where the new world put Buggy
        pose = next((p for tp, p in path if tp >= t), None)
        if pose is not None:
            ax.plot(pose["x"], pose["y"], marker="D", color="white", markeredgecolor="#6a1b9a", markersize=8,
                    zorder=5, linestyle="none")
    for t, on in data["estops"]:
        pose = _pose_at(path, t)
        if on and pose is not None:
            ax.plot(pose["x"], pose["y"], marker="X", color="#d00000", markeredgecolor="black", markersize=12,
                    zorder=5, linestyle="none")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    eaten = len(arena["eaten"])
    # each run of the world counts its bumps from 0: the counts the runs ended with, summed
    bumps = sum(run[-1][1].get("bumps", 0) for run in runs if run)
    ax.set_title(f"path ({path[-1][0] - path[0][0]:.0f} s): {eaten} food eaten, {bumps} bumps" if path else "path",
                 fontsize=10)
    legend = [Line2D([], [], color=c, linewidth=2.5, label=LABELS[k]) for k, c in COLOURS.items()]
    legend += [Line2D([], [], color="#5b3a1e", linewidth=3, label="crack"),
               Line2D([], [], marker="s", color="#2a9d3f", markeredgecolor="black", linestyle="none", label="food"),
               Line2D([], [], marker="o", color="white", markeredgecolor="black", linestyle="none", label="start"),
               Line2D([], [], marker="o", color="black", linestyle="none", label="end")]
    if any(on for _, on in data["estops"]):
        legend.append(Line2D([], [], marker="X", color="#d00000", markeredgecolor="black", linestyle="none",
                             label="estop"))
    if restarts:
        legend.append(Line2D([], [], marker="D", color="white", markeredgecolor="#6a1b9a", linestyle="none",
                             label=f"{data['world']} restarted: a new world"))
    # under the arena, as many rows as it takes: the figure is saved with room for all of them
    ax.legend(handles=legend, loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=4, fontsize=8, frameon=False)

    # hunger and fear over time, the active behaviour as a band underneath
    ts = mood_t
    bx.plot(ts, [m.get("hunger", 0.0) for _, m in mood], color="#7b2cbf", linewidth=1.6, label="hunger")
    bx.plot(ts, [m.get("fear", 0.0) for _, m in mood], color="#c62828", linewidth=1.2, label="fear")
    top = max([1.0] + [min(m.get("fear", 0.0), 3.0) for _, m in mood])
    band = -0.08 * top
    for (t0, m), (t1, _) in zip(mood, mood[1:]):
        bx.axvspan(t0, t1, ymin=0, ymax=0.05, color=COLOURS.get(m.get("doing"), "0.5"), linewidth=0)
    for t, _ in arena["eaten"]:
        bx.axvline(t, color="#2a9d3f", linewidth=0.8, alpha=0.6)
    for t in restarts:
        bx.axvline(t, color="#6a1b9a", linewidth=1.6, linestyle="-.")
        bx.annotate(f"{data['world']} restarted", (t, top), xytext=(3, -24), textcoords="offset points",
                    color="#6a1b9a", fontsize=8)
    for t, on in data["estops"]:  # estop on: red; released: grey
        bx.axvline(t, color="#d00000" if on else "0.4", linewidth=1.6, linestyle="--")
        bx.annotate("estop" if on else "estop off", (t, top), xytext=(3, -12), textcoords="offset points",
                    color="#d00000" if on else "0.4", fontsize=8)
    bx.set_ylim(band * 1.6, top * 1.05)
    bx.set_xlim(ts[0] if ts else 0, max(ts[-1], ts[0] + 0.1) if ts else 1)  # one sample: no empty span
    bx.set_xlabel("time (s)")
    bx.set_ylabel("level")
    bx.set_title("hunger and fear; band: the behaviour driving (green lines: food eaten)", fontsize=10)
    bx.legend(loc="upper right", fontsize=8)
    bx.grid(alpha=0.3)
    fig.suptitle(title or f"{recording.system or 'buggy'}: Buggy in an arena with {len(arena['cracks'])} cracks",
                 fontsize=12, parse_math=False)  # a title is text: "$5" is not mathtext
    fig.tight_layout()
    output = Path(output)
    fig.savefig(output, dpi=90, bbox_inches="tight")  # "tight": the legend below the arena included
    plt.close(fig)
    return output
