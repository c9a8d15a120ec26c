"""A recording that goes on in more files than one names them one way, `NAME_<n>.mcap`: the
members of a split recording and the file a run's recording goes on in after its recorder died.
The latter never takes a name that holds a file of this run (a member of its own split
recording), even with --force, which replaces only an earlier run's."""
import os
import time

from iotad.launcher.run.recording_paths import continuation_path, next_continuation, unused_recording_path, unwritable


def test_members_and_continuations_are_numbered_the_same_way(tmp_path):
    first = tmp_path / "fig2.mcap"
    assert continuation_path(first, 0) == tmp_path / "fig2_0.mcap"
    assert continuation_path(first, 3) == tmp_path / "fig2_3.mcap"
    assert next_continuation(first, 1) == tmp_path / "fig2_1.mcap"


def test_a_restarted_recorder_skips_the_members_of_its_own_split_recording(tmp_path):
    first = tmp_path / "rec.mcap"
    since = time.time()
    for n in range(3):  # this run's split recording: rec.mcap lists rec_0..rec_2
        (tmp_path / f"rec_{n}.mcap").write_bytes(b"member")
    assert next_continuation(first, 1) == tmp_path / "rec_3.mcap"
    assert next_continuation(first, 1, replace_before=since) == tmp_path / "rec_3.mcap"  # --force: still kept


def test_force_replaces_only_an_earlier_runs_file(tmp_path):
    first = tmp_path / "rec.mcap"
    earlier = tmp_path / "rec_1.mcap"
    earlier.write_bytes(b"an earlier run")
    os.utime(earlier, (time.time() - 3600, time.time() - 3600))
    since = time.time()
    assert next_continuation(first, 1) == tmp_path / "rec_2.mcap"  # kept without --force
    assert next_continuation(first, 1, replace_before=since) == earlier


def test_a_fresh_name_is_no_continuation_of_another_recording(tmp_path):
    stamped = tmp_path / "figure2-20261123-191000.mcap"
    stamped.write_bytes(b"a run of the same second")
    assert unused_recording_path(stamped) == tmp_path / "figure2-20261123-191000-2.mcap"


def test_one_writability_check_says_why_in_a_few_words(tmp_path):
    (tmp_path / "plain").write_text("x")
    assert unwritable(tmp_path) == "it is a directory"
    assert unwritable(tmp_path / "plain" / "rec.mcap") == f"{tmp_path / 'plain'} is not a directory"
    assert unwritable(tmp_path / "new" / "rec.mcap") is None and not (tmp_path / "new").exists()
    assert unwritable(tmp_path / "new" / "rec.mcap", make_folder=True) is None
    assert (tmp_path / "new").is_dir() and not (tmp_path / "new" / "rec.mcap").exists()
    assert "MiB free on its file system" in unwritable(tmp_path / "rec.mcap", make_folder=True, min_free_bytes=1 << 62)
