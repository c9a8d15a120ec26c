"""Input scripts: drive a system in virtual time from JSONL lines `{"t", "action", "index", "value"}`.

An optional `"iota"` names the leaf path the input goes to; without it the input goes to the
root's external channel named by `action`.
"""
from __future__ import annotations

import json
import math
from typing import Any, Iterable

from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine
from iotad.kernel.types import HUGE_INT


class ScriptError(Exception):
    """An input script line is malformed; the message names the line."""


def parse_script(lines: Iterable[str], source: str = "<script>") -> list[dict]:
    inputs = []
    last_t = -math.inf
    for number, line in enumerate(lines, 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        where = f"{source}:{number}"
        try:
            entry = json.loads(line)
        except json.JSONDecodeError as exc:
            raise ScriptError(f"{where}: not JSON: {exc.msg}") from None
        except RecursionError:
            raise ScriptError(f"{where}: nested too deeply to be an input") from None
        except ValueError:  # json reads no int of more than 4300 digits
            raise ScriptError(f"{where}: an integer of thousands of digits, {HUGE_INT}") from None
        if not isinstance(entry, dict):
            raise ScriptError(f"{where}: expected an object like {{\"t\": 0.0, \"action\": \"req\", ...}}")
        t, action, index = entry.get("t"), entry.get("action"), entry.get("index")
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) or t < 0:
            raise ScriptError(f"{where}: \"t\" must be a finite time >= 0, got {t!r}")
        if t < last_t:
            raise ScriptError(f"{where}: times must not go backwards ({t} after {last_t})")
        if not isinstance(action, str) or not action:
            raise ScriptError(f"{where}: \"action\" must name an input channel")
        if index is not None and (isinstance(index, bool) or not isinstance(index, int) or index < 0):
            raise ScriptError(f"{where}: \"index\" must be a whole number >= 0 or null")
        unknown = set(entry) - {"t", "action", "index", "value", "iota"}
        if unknown:
            raise ScriptError(f"{where}: unknown field(s) {sorted(unknown)}")
        last_t = t
        inputs.append({"t": float(t), "action": action, "index": index, "value": entry.get("value"),
                       "iota": entry.get("iota")})
    return inputs


def run_script(root: Any, inputs: Iterable[dict], until: float, policy: Any = None, **engine_options: Any) -> Engine:
    """Feed the inputs into `root` in virtual time up to `until`; the trace is `engine.trace`."""
    engine = Engine(root, VirtualClock(), policy, **engine_options)
    for entry in inputs:
        if entry["t"] <= until:
            engine.post(entry.get("iota"), entry["action"], entry.get("value"), entry.get("index"), t=entry["t"])
    engine.run(until)
    return engine
