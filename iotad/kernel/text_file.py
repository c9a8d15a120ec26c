"""Reading a text file a user named (a system file, a spec, an input script) with limits: a
device or FIFO named by mistake (/dev/zero, a pipe nobody writes) would be read for ever, and a
file of gigabytes is the wrong file, so both are refused with a reason, as an OSError."""
from __future__ import annotations

import os
import stat
from pathlib import Path

TEXT_FILE_MAX = 64 * 2**20  # bytes; the largest spec or input script seen is a few hundred KB


def read_text_file(path: str | os.PathLike, limit: int = TEXT_FILE_MAX) -> str:
    """The file's UTF-8 text. OSError (its strerror says why) for a device, a FIFO or a socket,
    for a file over `limit` bytes, and as `open` raises it; UnicodeDecodeError for binary data."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except OSError:
        mode = None  # let open() say what is wrong, in its own words
    if mode is not None and not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise OSError(0, "not a regular file (a device, a FIFO or a socket)", str(path))
    with path.open("rb") as file:
        data = file.read(limit + 1)
    if len(data) > limit:
        raise OSError(0, f"larger than {limit // 2**20} MiB: not a text file iotad reads", str(path))
    return data.decode("utf-8")
