"""Where recordings are written: the names of a recording's continuation files, a fresh name
for a run's recording, claiming a name, and whether an output file can be written at all.

In the launcher layer, below `iotad.recording`, because the launcher names the file a
recording goes on in after its recorder died and checks a recording's path before it starts
anything; the recorder and the command line import it from here.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path


def unwritable(path: str | Path, *, make_folder: bool = False, min_free_bytes: int = 0) -> str | None:
    """Why no file can be written at `path`, in a few words, or None: it is a directory, a file
    stands where a directory of its path should be, or the nearest directory that exists cannot
    be written in. With `make_folder` (a writer about to start: the recorder's file), its folder
    is created, the file system must have `min_free_bytes` free, and the file is opened for
    appending (and removed again if it was not there), which a read-only mount also refuses."""
    target = Path(path)
    if target.is_dir():
        return "it is a directory"
    for parent in target.parents:
        if parent.exists():
            if not parent.is_dir():
                return f"{parent} is not a directory"
            if not os.access(parent, os.W_OK):
                return f"cannot write in {parent}"
            break
    if not make_folder:
        return None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return f"cannot create its folder {target.parent}: {exc.strerror or exc}"
    try:
        free = shutil.disk_usage(target.parent).free
    except OSError as exc:
        return f"cannot see the free space of {target.parent}: {exc.strerror or exc}"
    if free < min_free_bytes:
        return (f"only {free / 2**20:.1f} MiB free on its file system "
                f"(at least {min_free_bytes // 2**20} MiB wanted)")
    existed = target.exists()
    try:
        with open(target, "ab"):
            pass
    except OSError as exc:
        return exc.strerror or str(exc)
    if not existed:
        target.unlink(missing_ok=True)
    return None


def continuation_path(path: str | Path, number: int) -> Path:
    """File `number` of a recording that goes on in more files than one: `fig2.mcap` ->
    `fig2_3.mcap`. The one scheme for both kinds: the members of a split recording (`iotad
    record --max-size`, numbered from 0, listed by the set file `path`), and the file a run's
    recording goes on in after its recorder died (numbered from 1, skipping names that hold a
    file: an earlier run's, or a member of this run's split recording)."""
    path = Path(path)
    return path.with_name(f"{path.stem}_{number}{path.suffix or '.mcap'}")


def next_continuation(first: str | Path, number: int, replace_before: float | None = None) -> Path:
    """`continuation_path(first, n)` for the first n >= `number` whose name holds no file: one
    there is an earlier run's (kept, as `-o` keeps one) or a member of this run's own split
    recording (`first` is then its set file). With `replace_before` (`--force`: a wall-clock
    time before this run wrote anything) a file last written before then is replaced; one this
    run wrote never is."""
    while True:
        candidate = continuation_path(first, number)
        try:
            written = candidate.stat().st_mtime
        except FileNotFoundError:
            return candidate
        if replace_before is not None and written < replace_before:
            return candidate
        number += 1


def existing_recording(path: str | Path) -> Path | None:
    """The file a new recording at `path` would replace: `path` itself, or the first member of a
    split recording of that name (`fig2_0.mcap`); None when there is none. Recordings are the
    evidence of a run: `run -o` and `record -o` replace one only when told to (--force)."""
    path = Path(path)
    for candidate in (path, continuation_path(path, 0)):
        if candidate.is_file() and (candidate != path or candidate.stat().st_size > 0):
            return candidate
    return None


def claim_file(path: str | Path) -> bool:
    """Create `path` empty, atomically: False if it is there already. A run claims its recording's
    name this way before anything writes it, so that two runs started together never share one
    file (each checked that no recording was there, then both wrote it). An empty file at the
    name is no recording (`existing_recording`): the writer replaces it."""
    try:
        os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
    except FileExistsError:
        return False
    return True


def unused_recording_path(path: str | Path, claim: bool = False) -> Path:
    """`path`, or `path` with -2, -3... before its suffix: the first name no recording holds (two
    runs started within the same second would otherwise share a time-stamped default name);
    with `claim`, the first one this process could create (`claim_file`). Not `_2`: this is
    another run's recording, not a continuation, and `name_2.mcap` may be a member that a split
    recording named `name.mcap`, started the same second, is about to create."""
    path = Path(path)
    candidate, number = path, 2
    while existing_recording(candidate) is not None or (claim and not _claimed(candidate)):
        candidate = path.with_name(f"{path.stem}-{number}{path.suffix}")
        number += 1
    return candidate


def _claimed(path: Path) -> bool:
    path.parent.mkdir(parents=True, exist_ok=True)
    return claim_file(path)
