"""One host's part of a system spread over hosts, as its agent runs it:
`python -m iotad.launcher.run.host_part PART.json`, where PART.json (written by the agent,
iotad/launcher/hosts/agent.py) holds the hub's system file text and path, where this machine has each
file it names, and the typed options of this host's launcher (`RunOptions`). Checks the system
and runs it with `run_real_time`; its lines and exit status are those of `iotad run --host`:
an error is one line, `iotad: error: ...` (exit 2), Ctrl-C exits 130."""
from __future__ import annotations

import json
import os
import sys
import threading
from pathlib import Path


def run_part(part: dict) -> int:
    """Run the part `part` describes (the JSON of PART.json); raises `SystemFileError`, `RunError`
    or ValueError with one line."""
    from iotad.launcher.system.declaration import parse_declaration
    from iotad.launcher.options import RunOptions
    from iotad.launcher.run.run_system import run_real_time
    from iotad.launcher.system.system_file import SystemFileError, check_system

    text, path, files = part.get("system"), part.get("path"), part.get("files", {})
    if not isinstance(text, str) or not isinstance(path, str) or not isinstance(files, dict):
        raise ValueError("a host's part needs the system file's 'system' text, its 'path' and its 'files'")
    options = RunOptions.from_json(part.get("run", {}))
    declaration = parse_declaration(text, path, base=Path(path).parent, files=files)
    try:
        system = check_system(declaration)
    except SystemFileError as exc:
        raise SystemFileError([str(exc) if len(exc.errors) == 1 else
                               f"{len(exc.errors)} problems in the system file:\n{exc}"]) from None
    return run_real_time(system, options)


def main(argv: list[str]) -> int:
    from iotad.launcher.run.run_system import RunError
    from iotad.launcher.system.system_file import SystemFileError

    if len(argv) != 1:
        print("usage: python -m iotad.launcher.run.host_part PART.json", file=sys.stderr)
        return 2
    try:
        with open(argv[0], encoding="utf-8") as stream:
            code = run_part(json.load(stream))
    except (SystemFileError, RunError, ValueError, OSError) as exc:
        print(f"iotad: error: {exc}", file=sys.stderr)
        code = 2
    except KeyboardInterrupt:
        print("", file=sys.stderr)
        code = 130
    except Exception as exc:  # noqa: BLE001 - a bug or an unforeseen input: still one line
        print(f"iotad: error: unexpected {type(exc).__name__}: {exc}", file=sys.stderr)
        code = 1
    return code


if __name__ == "__main__":
    code = main(sys.argv[1:])
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    # as `iotad` does: threads a node's code left (its init ran in the check) are not waited for
    if any(t is not threading.main_thread() and not t.daemon and t.is_alive() for t in threading.enumerate()):
        os._exit(code)
    sys.exit(code)
