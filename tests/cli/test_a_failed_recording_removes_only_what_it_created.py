"""A run or recorder that writes nothing removes the empty file it created for its recording, and
nothing else: not a device named as the output (`-o /dev/full` to test a full disk, `-o
/dev/null`), not a file that was there before (`--force` names one). Root could remove a device
node; the device tests make their own in the test's folder, never the real ones."""
import os
import stat
from pathlib import Path

import pytest

from iotad.cli import drop_empty_claim, main

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = str(ROOT / "examples" / "figure2.toml")


def device(path: Path, minor: int) -> Path:
    """A character device like /dev/null (minor 3) or /dev/full (minor 7), at `path`."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, minor))
    except PermissionError:
        pytest.skip("making a device node needs root")
    return path


def test_a_run_that_cannot_write_to_a_full_device_leaves_the_device(tmp_path, capsys):
    full = device(tmp_path / "full", 7)
    code = main(["run", FIGURE2, "--virtual", "--until", "1", "-o", str(full), "--force", "--plain"])
    assert code != 0
    assert "No space left on device" in capsys.readouterr().err
    assert stat.S_ISCHR(os.lstat(full).st_mode)  # still there


def test_a_device_as_the_output_needs_force_and_is_named_for_what_it_is(tmp_path, capsys):
    null = device(tmp_path / "null", 3)
    assert main(["run", FIGURE2, "--virtual", "--until", "1", "-o", str(null), "--plain"]) == 2
    assert "not a plain file (a device, a FIFO or a link)" in capsys.readouterr().err
    assert main(["run", FIGURE2, "--virtual", "--until", "1", "-o", str(null), "--force", "--plain"]) == 0
    assert stat.S_ISCHR(os.lstat(null).st_mode)


def test_a_recorder_that_met_no_hub_leaves_a_device_named_as_its_output(tmp_path, capsys):
    null = device(tmp_path / "null", 3)
    code = main(["record", "iota/x/**", "-o", str(null), "--force", "--connect", "tcp/127.0.0.1:9",
                 "--duration", "0.5", "--quiet"])
    assert code == 2 and "nothing recorded" in capsys.readouterr().err
    assert stat.S_ISCHR(os.lstat(null).st_mode)


def test_only_an_empty_regular_file_is_dropped(tmp_path):
    empty, kept, fifo = tmp_path / "empty.mcap", tmp_path / "kept.mcap", tmp_path / "fifo"
    empty.write_bytes(b"")
    kept.write_bytes(b"x")
    os.mkfifo(fifo)
    for path in (empty, kept, fifo, tmp_path / "missing.mcap", None):
        drop_empty_claim(path)
    assert not empty.exists() and kept.read_bytes() == b"x" and stat.S_ISFIFO(os.lstat(fifo).st_mode)
