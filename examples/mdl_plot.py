"""Plot an MDL interpreter's run from a recording: each joint's setpoint and measured position, the
program running at each moment, and every atom end (docs/mdl.md).

    .venv/bin/python examples/mdl_plot.py mdl_arm.mcap -o mdl_arm.png [--node mdl] [--motor motor]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from iotad.recording.mcap_reader import read_recording  # noqa: E402

COLOURS = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("recording")
    parser.add_argument("-o", "--output", required=True)
    parser.add_argument("--node", default="mdl", help="the interpreter's node (mdl)")
    parser.add_argument("--motor", default="motor", help="the node whose joint_states are measured (motor)")
    args = parser.parse_args(argv)
    try:
        trace = read_recording(args.recording).trace()
    except Exception as exc:  # noqa: BLE001 - any unreadable file: say so, no traceback
        print(f"mdl_plot: cannot read {args.recording}: {exc}", file=sys.stderr)
        return 2
    mine = [e for e in trace if e["iota"] == args.node and e["kind"] in ("output", "input")]
    setpoints = [(e["t"], e["value"]["position"]) for e in mine if e["action"] == "setpoints"]
    if not setpoints:
        print(f"mdl_plot: no setpoints from node {args.node!r} in {args.recording}", file=sys.stderr)
        return 2
    measured = [(e["t"], e["value"]["position"]) for e in trace
                if e["iota"] == args.motor and e["action"] == "joint_states" and e["kind"] == "output"]

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bar) = plt.subplots(2, 1, figsize=(11, 6), sharex=True, gridspec_kw={"height_ratios": [5, 1]})
    joints = len(setpoints[0][1])
    for j in range(joints):
        colour = COLOURS[j % len(COLOURS)]
        ax.plot([t for t, _ in setpoints], [p[j] for _, p in setpoints], color=colour, lw=1.2,
                label=f"joint {j + 1} setpoint")
        if measured:
            ax.plot([t for t, _ in measured], [p[j] for _, p in measured], color=colour, lw=0.8, ls="--")
    for e in mine:
        if e["action"] == "atom_end" and e["kind"] == "output":
            v = e["value"]
            style = "-" if v["end"] == "DONE" else ":"
            ax.axvline(e["t"], color="grey", ls=style, lw=0.8)
            text = f"{v['program']}[{v['behaviour']}.{v['atom']}] {v['end'].lower()}"
            if v["condition"]:
                text += f": {v['condition']}"
            ax.annotate(text, (e["t"], 1.0), xycoords=("data", "axes fraction"), rotation=90, fontsize=7,
                        va="top", ha="right")
    # which program runs: from each mdl_command to the next command or its program_end
    spans, current, since = [], None, 0.0
    for e in mine:
        if e["action"] == "mdl_command" and e["kind"] == "input":
            if current is not None:
                spans.append((current, since, e["t"]))
            current, since = e["value"].get("id", "mode"), e["t"]
        elif e["action"] == "program_end" and e["kind"] == "output" and e["value"]["program"] == current \
                and e["value"]["end"] != "PREEMPTED":
            spans.append((current, since, e["t"]))
            current = None
    if current is not None:
        spans.append((current, since, setpoints[-1][0]))
    names = sorted({name for name, _, _ in spans})
    for name, start, end in spans:
        k = names.index(name)
        bar.broken_barh([(start, end - start)], (0, 1), color=COLOURS[(k + 3) % len(COLOURS)], alpha=0.6)
        bar.text((start + end) / 2, 0.5, name, ha="center", va="center", fontsize=8)
    bar.set_yticks([])
    bar.set_ylabel("program")
    bar.set_xlabel("t (s)")
    ax.set_ylabel("position (rad): setpoint solid, measured dashed")
    ax.legend(loc="lower right", fontsize=7, ncol=3)
    ax.set_title(f"MDL interpreter '{args.node}': {Path(args.recording).name}")
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)
    print(f"mdl_plot: wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
