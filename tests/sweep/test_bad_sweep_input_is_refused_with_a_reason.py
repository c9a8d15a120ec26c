"""A sweep that cannot be what its user meant stops before any run, with one line that says why:
a parameter the system does not have, a range without --sample, a folder holding another sweep
or something else, a bad sweep file; and a system file's [sweep] table is checked with the rest."""
import pytest

from iotad.cli import main
from iotad.launcher.system.system_file import SystemFileError, load_system


def refused(capsys, *argv) -> str:
    assert main(["sweep", *map(str, argv)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("iotad: error: ") and "Traceback" not in err
    return err


def test_a_parameter_the_system_lacks(system, tmp_path, capsys):
    assert "no node 'tickr'" in refused(capsys, system, "--set", "tickr.period=1,2", "--until", "1", "-o", tmp_path / "a")
    err = refused(capsys, system, "--set", "ticker.perod=1,2", "--until", "1", "-o", tmp_path / "a")
    assert "no parameter 'perod'" in err and "period" in err
    assert not (tmp_path / "a").exists()  # nothing made for a sweep that never started


def test_a_range_needs_sample_and_until_is_needed(system, tmp_path, capsys):
    assert "--sample K" in refused(capsys, system, "--set", "ticker.period=0.1..0.3", "--until", "1", "-o", tmp_path / "a")
    assert "--until SECONDS is needed" in refused(capsys, system, "--set", "ticker.period=1", "-o", tmp_path / "a")
    assert "LOW <= HIGH" in refused(capsys, system, "--set", "ticker.period=0.3..0.1", "--sample", "2",
                                    "--until", "1", "-o", tmp_path / "a")


def test_a_folder_of_another_sweep_or_of_something_else(system, tmp_path, capsys):
    assert main(["sweep", str(system), "--set", "ticker.period=0.5", "--until", "1", "-o", str(tmp_path / "s"),
                 "--plain"]) == 0
    capsys.readouterr()
    assert "holds another sweep" in refused(capsys, system, "--set", "ticker.period=0.6", "--until", "1",
                                            "-o", tmp_path / "s")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    assert "no sweep's folder" in refused(capsys, system, "--until", "1", "-o", tmp_path / "other")


def test_a_bad_sweep_file(tmp_path, capsys, system):
    file = tmp_path / "bad-sweep.toml"
    file.write_text(f'[sweep]\nsystem = "{system}"\nuntil = 1\nsedes = 3\n')
    assert "unknown key 'sedes'" in refused(capsys, file, "-o", tmp_path / "a")
    file.write_text(f'[sweep]\nsystem = "{system}"\nuntil = 1\n[sweep.set]\n"ticker.period" = 0.5\n')
    assert "expected a list of values" in refused(capsys, file, "-o", tmp_path / "a")


def test_a_system_files_sweep_table_is_checked(tmp_path, system, capsys):
    text = system.read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('metrics = "', 'metric = "'))
    with pytest.raises(SystemFileError, match=r"\[sweep\]: unknown key 'metric'"):
        load_system(bad, check=False)
    bad.write_text(text.replace(':tick_metrics"', '"'))  # no function named
    with pytest.raises(SystemFileError, match="metrics must be"):
        load_system(bad, check=False)
    gone = tmp_path / "gone.toml"  # `iotad run` needs no hook; `iotad sweep` refuses a missing one
    gone.write_text(text.split("[sweep]")[0] + '[sweep]\nmetrics = "nowhere.py:f"\n')
    assert load_system(gone, check=False).sweep_metrics == f"{tmp_path / 'nowhere.py'}:f"
    assert "nowhere.py:f: no such file" in refused(capsys, gone, "--until", "1", "-o", tmp_path / "a")
    assert load_system(system, check=False).sweep_metrics.endswith("sweep_iotas.py:tick_metrics")
