"""What `iotad run --virtual` prints of a system's `[goals]` after the run: whether each held,
measured from the run's recording (docs/stress.md)."""
from __future__ import annotations

from pathlib import Path


def report_goals(system, recording: Path | None, violations: int) -> bool | None:
    """Print the verdict of each goal of `system` on the run recorded in `recording`; True when
    every one held, False when one did not (or could not be measured), None without goals."""
    from iotad.launcher.goals import all_met, judge
    from iotad.recording.mcap_reader import read_recording
    from iotad.recording.run_metrics import run_metrics

    goals = list(system.goals)
    if not goals:
        return None
    if recording is None:
        print("  goals: not judged (no recording: its metrics are measured from one)")
        return False
    try:
        metrics = run_metrics(read_recording(recording), system.sweep_metrics, violations)
    except Exception as exc:  # noqa: BLE001 - a hook that fails: the goals are not judged, said in one line
        print(f"  goals: not judged: the metrics hook {system.sweep_metrics} failed: {type(exc).__name__}: {exc}")
        return False
    verdicts = judge(goals, metrics)
    print(f"  goals: {sum(v.met for v in verdicts)} of {len(verdicts)} held")
    for verdict in verdicts:
        print(f"    {verdict.line()}")
    return all_met(verdicts)
