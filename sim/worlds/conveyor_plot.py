"""The conveyor arm's run (the paper's Figure 1, examples/conveyor.toml) as a picture: the objects
over time (appeared, held, placed in the bin, missed, dropped) with the pick goals, and below it
the scheduler's timeline: which requester's MDL program held the arm, and the acks.

A recording is a conveyor's when a node outputs `tally` (the world's count of objects) and a node
outputs `mdl_command` (the scheduler). Who held the arm: the requester whose `req[i]` carried the
program id that `mdl_command` sent, from then until the next `mdl_command`. Everything comes from
the nodes' trace events, so a virtual-time run and a real-time run draw the same way.
"""
from __future__ import annotations

from pathlib import Path

from iotad.recording.mcap_format import RecordingError
from iotad.recording.mcap_reader import Recording
from iotad.recording.timeline_plot import ACK_STYLE, requester_names

COUNTS = (("spawned", "on the belt so far", "#777777"), ("placed", "placed in the bin", "#2a9d3f"),
          ("missed", "missed (fell off the belt's end)", "#c62828"), ("dropped", "dropped", "#e08a00"))
HOLDER_COLOURS = ("#3a6ea5", "#e08a00", "#2a9d3f", "#8e44ad")


def matches(recording: Recording) -> bool:
    channels = {topic.rsplit("/", 1)[-1] for topic in recording.topics()}
    return {"tally", "mdl_command"} <= channels


def conveyor_data(recording: Recording) -> dict:
    """tally [(t, counts)], picks [t], spans [(start, end, requester index)], acks [(t, index, ack)],
    the scheduler's node and the end time; RecordingError if it is no conveyor recording."""
    tally, picks, commands, acks, owners = [], [], [], [], {}
    scheduler, world, end = None, None, 0.0
    unit = recording.time_unit  # events count spec units; the picture shows seconds
    for event in recording.trace():
        t, kind, action = float(event.get("t", 0.0)) * unit, event.get("kind"), event.get("action")
        end = max(end, t)
        value = event.get("value")
        if kind == "output" and action == "tally":
            tally.append((t, value))
            world = event.get("node")
        elif kind == "output" and action == "pick":
            picks.append(t)
        elif kind == "input" and action == "req" and isinstance(value, dict) and isinstance(value.get("control"), dict):
            owners[value["control"].get("id")] = int(event.get("index") or 0)
        elif kind == "output" and action == "mdl_command" and isinstance(value, dict):
            scheduler = event.get("node")
            commands.append((t, owners.get(value.get("id"), -1)))
        elif kind == "output" and action == "ack":
            acks.append((t, int(event.get("index") or 0), value))
    if not tally or scheduler is None:
        raise RecordingError("not a conveyor recording: no node outputs both 'tally' and 'mdl_command'")
    spans = [(t, commands[k + 1][0] if k + 1 < len(commands) else end, who) for k, (t, who) in enumerate(commands)]
    restarts = [t * unit for t in recording.restart_times(world)]
    return {"tally": _across_restarts(sorted(tally, key=lambda p: p[0]), restarts), "picks": picks, "spans": spans,
            "acks": acks, "scheduler": scheduler, "end": end, "world": world, "restarts": restarts}


def _across_restarts(tally: list[tuple[float, dict]], restarts: list[float]) -> list[tuple[float, dict]]:
    """The world's counts over the whole run: a restarted world node counts from 0 in a new
    world, so each count (but `held`, an object in the hand now) goes on from where the runs
    before it ended."""
    out, carried, last, cuts = [], {}, None, sorted(restarts)
    for t, counts in tally:
        while cuts and t >= cuts[0]:
            cuts.pop(0)
            if last is not None:
                carried = {key: carried.get(key, 0) + last.get(key, 0) for key, _, _ in COUNTS}
        last = counts
        out.append((t, dict(counts, **{key: counts.get(key, 0) + carried.get(key, 0) for key, _, _ in COUNTS})))
    return out


def plot(recording: Recording, output: str | Path, title: str | None = None) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = conveyor_data(recording)
    names = requester_names(recording, data["scheduler"])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 1.4]})
    times = [t for t, _ in data["tally"]] + [data["end"]]
    for key, label, colour in COUNTS:
        values = [c[key] for _, c in data["tally"]]
        top.step(times, values + values[-1:], where="post", color=colour, lw=2, label=f"{label}: {values[-1]}")
    held = [c["held"] for _, c in data["tally"]]
    top.fill_between(times, 0, held + held[-1:], step="post", color="#3a6ea5", alpha=0.25, label="an object in the hand")
    for k, t in enumerate(data["picks"]):
        top.axvline(t, color="#3a6ea5", lw=0.6, ls=":", label="pick goal (planning)" if k == 0 else None)
    for k, t in enumerate(data["restarts"]):  # a new world: its counts go on from the old one's
        top.axvline(t, color="#6a1b9a", lw=1.6, ls="-.",
                    label=f"{data['world']} restarted: a new world" if k == 0 else None)
    final = data["tally"][-1][1]
    top.set_ylabel("objects")
    top.set_title(title or f"conveyor arm: {final['placed']} of {final['spawned']} objects placed in the bin "
                           f"({final['missed']} missed, {final['dropped']} dropped)",
                  parse_math=False)  # a title is text: "$5" is not mathtext
    top.legend(loc="upper left", fontsize=8)
    top.grid(alpha=0.3)

    rows = sorted({who for _, _, who in data["spans"] if who >= 0} | {i for _, i, _ in data["acks"]})
    label_of = {i: names.get(i, f"req[{i}]") for i in rows}
    for start, stop, who in data["spans"]:
        if who >= 0:
            bottom.barh(rows.index(who), stop - start, left=start, height=0.6,
                        color=HOLDER_COLOURS[who % len(HOLDER_COLOURS)], alpha=0.85)
    seen = set()
    for t, who, ack in data["acks"]:
        marker, colour = ACK_STYLE.get(ack, ("o", "black"))
        bottom.scatter([t], [rows.index(who) + 0.38], marker=marker, color=colour, s=28, zorder=3,
                       label=ack if ack not in seen else None)
        seen.add(ack)
    bottom.set_yticks(range(len(rows)), [label_of[i] for i in rows])
    bottom.set_ylim(-0.6, len(rows) - 0.1)
    bottom.set_xlabel("time (s)")
    bottom.set_title("who held the arm (the program on mdl_command), and the scheduler's acks", fontsize=9)
    if seen:
        bottom.legend(loc="upper right", fontsize=8, ncol=3)
    bottom.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    path = Path(output)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
