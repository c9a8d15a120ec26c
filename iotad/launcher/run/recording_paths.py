"""Where recordings are written: the names of a recording's continuation files, a fresh name
for a run's recording, claiming a name, and whether an output file can be written at all.

In the launcher layer, below `iotad.recording`, because the launcher names the file a
recording goes on in after its recorder died and checks a recording's path before it starts
anything; the recorder and the command line import it from here.
"""
from __future__ import annotations

import os
import shutil
import stat
import time
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


# ---------------------------------------------------------------------------- claims
class RecordingClaimError(Exception):
    """A recording name that a run may not write: one line for the user."""


def new_recording(path: str, force: bool, option: str = "-o") -> None:
    """Refuse, with one line, to write a recording over one that is already there, unless `force`."""
    found = None if force else existing_recording(path)
    if found is not None:
        info = found.stat()
        written = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(info.st_mtime))
        raise RecordingClaimError(f"{option} {path}: a recording is already there ({found}, {info.st_size:,} bytes, "
                                 f"written {written}); name another file, or add --force to replace it")


def claim_recording(path: str, force: bool, option: str = "-o") -> bool:
    """`new_recording`'s check, then the name claimed (`claim_file`): of two runs started together
    with the same `-o`, one writes it and the other is refused here. True if this call created
    the (empty) file, which its caller removes should nothing be written to it."""
    new_recording(path, force, option)
    if force:
        return False
    try:
        if claim_file(path):
            return True
    except OSError:
        return False  # a path that cannot be written: the writer says so in its own words
    if os.path.exists(path) and not is_regular_file(path):
        raise RecordingClaimError(f"{option} {path}: not a plain file (a device, a FIFO or a link); name a file, "
                                  "or add --force to write the recording there anyway")
    raise RecordingClaimError(f"{option} {path}: an empty file is there: another run has just claimed it for its "
                              "recording (or one stopped before writing any); name another file, or add --force "
                              "to replace it")


def drop_empty_claim(path: str | os.PathLike | None) -> None:
    """Remove a recording file this run claimed (`claim_recording` returned True) that nothing
    was written to (the run stopped first). Only an empty regular file: never a device such as
    /dev/null, and never what was at the path before (call it only for a path this run created)."""
    if path is None:
        return
    try:
        if is_regular_file(path) and os.path.getsize(path) == 0:
            os.unlink(path)
    except OSError:
        pass


def is_regular_file(path: str | os.PathLike) -> bool:
    """Whether `path` is a plain file (not a device, a FIFO or a folder), without following a
    symbolic link: what a command may remove of its own output."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False
