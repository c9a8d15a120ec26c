"""A run's metrics from its recording: what the system file's `[sweep] metrics` hook measures,
plus `violations` (the violation events recorded), the numbers `[goals]` are judged on."""
from __future__ import annotations

import math
from typing import Any

from iotad.kernel.python_loader import load_object


def hook_metrics(recording: Any, hook: str | None) -> dict[str, Any]:
    """The hook's dict for `recording` (a `Recording`), numbers kept, anything else as text."""
    if not hook:
        return {}
    values = load_object(hook)(recording)
    if not isinstance(values, dict):
        raise TypeError(f"metrics hook {hook} returned {type(values).__name__}, not a dict")
    out: dict[str, Any] = {}
    for name, value in values.items():
        if isinstance(value, bool):
            value = int(value)
        elif not isinstance(value, (int, float, str)) or (isinstance(value, float) and not math.isfinite(value)):
            value = str(value)
        out[str(name)] = value
    return out


def run_metrics(recording: Any, hook: str | None, violations: int | None = None) -> dict[str, Any]:
    """`hook_metrics` and `violations`: the count given (the run's own), else counted in the
    recording. A hook's own `violations` wins."""
    metrics = hook_metrics(recording, hook)
    if "violations" not in metrics:
        metrics["violations"] = violations if violations is not None else len(recording.violations())
    return metrics
