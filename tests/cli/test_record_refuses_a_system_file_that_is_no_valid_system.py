"""`iotad record --system-file` refuses a file that is TOML but no valid system, in the words of
`iotad run --check`, before it connects or writes anything: a binding to a channel no node has,
a spec with a syntax error, a parameter the IOTA lacks. A recording stores its system file for
check and replay, which would fail on it later. The recorder `iotad run` starts (on a file it
has checked) loads no node code; a valid system file is still taken at once."""
import pytest

from iotad.cli import main
from iotad.launcher.system.system_file import SystemFileError, load_system
from launcher_helpers import IOTAS

DEAD = ["--connect", "tcp/127.0.0.1:9", "--duration", "3", "--quiet"]  # no hub: only a refusal ends it early

CASES = {
    "a channel no node has": (f'python = "{IOTAS}:Source"\n[[bind]]\nfrom = "a.nochan"\nto = "a.out"\n',
                              "node 'a' has no external channel 'nochan'"),
    "a spec with a syntax error": ('spec = "bad.iota"\n', "unexpected 'garbage'"),
    "a parameter the IOTA lacks": (f'python = "{IOTAS}:Source"\nparams = {{ nonparam = 3 }}\n',
                                   "Source has no parameter(s) ['nonparam']"),
}


def system(tmp_path, node: str):
    (tmp_path / "bad.iota").write_text("iota x: a(int)/1 -> b(int)/1 { garbage }\n")
    path = tmp_path / "s.toml"
    path.write_text(f'[system]\nname = "s"\n[[node]]\nname = "a"\n{node}')
    return path


@pytest.mark.parametrize("case", sorted(CASES))
def test_record_refuses_it_with_the_checks_own_words(tmp_path, capsys, case):
    node, words = CASES[case]
    path = system(tmp_path, node)
    with pytest.raises(SystemFileError) as checked:
        load_system(path)
    out = tmp_path / "r.mcap"
    assert main(["record", "-o", str(out), "--system-file", str(path), *DEAD]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"iotad: error: --system-file {path}: "), err
    assert words in err and checked.value.errors[0].splitlines()[0] in err, err
    assert "waiting for a hub" not in err and not out.exists()


def test_a_valid_system_file_is_taken(tmp_path, capsys):
    path = system(tmp_path, f'python = "{IOTAS}:Source"\n')
    out = tmp_path / "r.mcap"
    main(["record", "-o", str(out), "--system-file", str(path), *DEAD[:-1]])
    assert "waiting for a hub" in capsys.readouterr().err   # past the check, to the connection


def test_the_launchers_recorder_checks_the_form_only(tmp_path, capsys):
    node, _ = CASES["a parameter the IOTA lacks"]
    path = system(tmp_path, node)
    main(["record", "-o", str(tmp_path / "r.mcap"), "--system-file", str(path), "--from-launcher", *DEAD[:-1]])
    assert "waiting for a hub" in capsys.readouterr().err
