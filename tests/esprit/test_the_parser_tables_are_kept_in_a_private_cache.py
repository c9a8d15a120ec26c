"""Every process that reads an ESPRIT spec (each node host, the launcher, the recorder, the tools)
needs the LALR tables of the grammar; building them costs about 0.25 s of CPU each time, so they
are kept in `$XDG_CACHE_HOME/iotad`, which only this user may write (lark unpickles the file)."""
import os
import subprocess
import sys
from pathlib import Path

SPEC = Path(__file__).resolve().parents[2] / "examples" / "behaviours.iota"
PARSE = ("from iotad.esprit.errors import Source; from iotad.esprit.parser import parse; "
         "from iotad.esprit.expressions import parse_expression; "
         f"program = parse(Source(open({str(SPEC)!r}).read(), 'behaviours.iota')); "
         "print(len(program.decls), type(parse_expression('a + 1 < b')).__name__)")


def parse_in_a_process(cache_home: Path) -> str:
    done = subprocess.run([sys.executable, "-c", PARSE], capture_output=True, text=True, timeout=60,
                          env={**os.environ, "XDG_CACHE_HOME": str(cache_home)})
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and done.stderr == "", done.stderr
    return done.stdout.strip()


def tables(cache_home: Path) -> dict[str, float]:
    folder = cache_home / "iotad"
    return {p.name: p.stat().st_mtime_ns for p in folder.glob("*.tables")} if folder.exists() else {}


def test_the_first_process_writes_the_tables_and_the_next_one_reads_them(tmp_path):
    first = parse_in_a_process(tmp_path)
    written = tables(tmp_path)
    assert sorted(name.split("-")[1] for name in written) == ["expr", "start"]
    assert (tmp_path / "iotad").stat().st_mode & 0o777 == 0o700
    assert parse_in_a_process(tmp_path) == first
    assert tables(tmp_path) == written  # read, not written again


def test_a_damaged_cache_file_is_built_again_and_parsing_is_unchanged(tmp_path):
    first = parse_in_a_process(tmp_path)
    for name in tables(tmp_path):
        (tmp_path / "iotad" / name).write_bytes(b"not the tables\n\x80\x04garbage")
    assert parse_in_a_process(tmp_path) == first
    for name in tables(tmp_path):
        assert (tmp_path / "iotad" / name).stat().st_size > 1000  # written whole again


def test_a_folder_other_users_may_write_is_not_used(tmp_path):
    (tmp_path / "iotad").mkdir(mode=0o777)
    os.chmod(tmp_path / "iotad", 0o777)  # past the umask
    first = parse_in_a_process(tmp_path)
    assert first.split()[1] == "Binary"
    assert tables(tmp_path) == {}
