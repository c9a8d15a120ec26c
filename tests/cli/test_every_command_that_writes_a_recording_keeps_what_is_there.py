"""Every command that writes a recording keeps one that is there, beyond `-o` (see
test_recordings_are_never_overwritten_unless_forced.py): `iotad record` claims its name as
`iotad run -o` does, so of two started together on one -o the second is refused instead of both
writing the file; `iotad export` and `iotad recover` never write into a file of the recording they
read, --force or not (a member of a split set was destroyed while being copied); a split set's
numbered files skip a name that is taken (tests/recording/test_split_recordings.py); and
`iotad export --ros2 --force` never removes a bag folder that holds the recording it exports."""
import shutil
from pathlib import Path

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = str(ROOT / "examples" / "figure2.toml")
DEAD_HUB = ["--connect", "tcp/127.0.0.1:9", "--duration", "1", "--quiet"]


def test_record_refuses_a_name_another_recorder_has_just_claimed(tmp_path, capsys):
    out = tmp_path / "r.mcap"
    out.write_bytes(b"")  # what a recorder started a moment before has created
    assert main(["record", "iota/x/**", "-o", str(out), *DEAD_HUB]) == 2
    assert "another run has just claimed it" in capsys.readouterr().err
    assert out.exists() and out.read_bytes() == b""  # the other's claim, left alone


def test_record_that_writes_nothing_leaves_no_claim_behind(tmp_path, capsys):
    out = tmp_path / "sub" / "r.mcap"
    assert main(["record", "iota/x/**", "-o", str(out), *DEAD_HUB]) == 2
    assert "nothing recorded, no file written" in capsys.readouterr().err
    assert not out.exists()
    assert main(["record", "iota/x/**", "-o", str(out), *DEAD_HUB]) == 2  # the name is free again
    assert "another run has just claimed it" not in capsys.readouterr().err


def split_set(tmp_path) -> tuple[Path, Path]:
    """A recording read as a split set of one member: run.mcap lists run_0.mcap."""
    from iotad.launcher.run.recording_paths import continuation_path
    from iotad.recording.mcap_sink import write_set_file

    whole = tmp_path / "whole.mcap"
    assert main(["run", FIGURE2, "--virtual", "--until", "2", "-o", str(whole), "--plain"]) == 0
    info = dict(read_recording(whole).info)
    member = continuation_path(tmp_path / "run.mcap", 0)
    shutil.copy(whole, member)
    write_set_file(tmp_path / "run.mcap", "s1", [member.name], info)
    return tmp_path / "run.mcap", member


def test_export_and_recover_never_write_into_the_set_they_read(tmp_path, capsys):
    set_file, member = split_set(tmp_path)
    before = member.read_bytes()
    assert read_recording(set_file).files == [str(member)]
    capsys.readouterr()
    for command in (["export", str(set_file), "--json"], ["recover", str(set_file)]):
        assert main([*command, "-o", str(member), "--force"]) == 2, command
        assert f"-o {member}: is a file of the recording being read" in capsys.readouterr().err
    assert member.read_bytes() == before


def test_a_rosbag_export_never_removes_the_bag_that_holds_the_recording(tmp_path, capsys):
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")  # a bag, as --force wants
    recording = bag / "run.mcap"
    assert main(["run", FIGURE2, "--virtual", "--until", "1", "-o", str(recording), "--plain"]) == 0
    before = recording.read_bytes()
    capsys.readouterr()
    assert main(["export", str(recording), "--ros2", "-o", str(bag), "--force"]) == 2
    assert f"-o {bag}: holds the recording being exported" in capsys.readouterr().err
    assert recording.read_bytes() == before
