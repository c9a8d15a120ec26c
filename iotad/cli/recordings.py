"""How a command reads a recording: the file checked first, so that a bad one is one line
(`iotad: error: ...`), and a long read shows its progress on stderr."""
from __future__ import annotations

import sys


def _reading(file: str, done: int, size: int) -> None:
    """Progress of a long read (every reading command loads the recording first), on stderr."""
    print(f"reading {file}: {100 * done / max(size, 1):3.0f}% ({done / 1e6:.1f} of {size / 1e6:.1f} MB)",
          file=sys.stderr, flush=True)


def load(path: str, salvage: bool = False):
    """Read a recording for a command; a bad file is a one-line error. `salvage`: a damaged
    recording gives what comes before the damage (`Recording.damaged` says what) instead."""
    import os

    from iotad.cli import CliError
    from iotad.recording.mcap_format import RecordingError
    from iotad.recording.mcap_reader import read_recording
    if os.path.isdir(path):
        raise CliError(f"{path}: is a directory, not an MCAP recording")
    if not os.path.exists(path):
        raise CliError(f"{path}: no such file")
    if os.path.getsize(path) == 0:
        raise CliError(f"{path}: empty file, not an MCAP recording")
    try:
        with open(path, "rb") as handle:
            magic = handle.read(5)
    except OSError as exc:
        raise CliError(f"{path}: {exc.strerror or exc}") from None
    if magic != b"\x89MCAP":
        raise CliError(f"{path}: not an MCAP recording (it does not start with the MCAP magic bytes)")
    try:
        return read_recording(path, salvage=salvage, progress=_reading)
    except RecordingError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{path}: {exc.strerror or exc}") from None
