"""System files: every check has a file that trips it and a near twin that passes."""
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.launcher.system.system_file import SystemFileError, load_system, with_port

ROOT = Path(__file__).resolve().parents[2]
IOTAS = Path(__file__).resolve().parents[1] / "system_iotas.py"


def write(tmp_path: Path, body: str, name: str = "sys.toml") -> Path:
    text = body.replace("IOTAS", str(IOTAS))
    if "[system]" not in text:
        text = '[system]\nname = "t"\n' + text
    path = tmp_path / name
    path.write_text(text)
    return path


SOURCE_SINK = """{external}
[[node]]
name = "src"
python = "IOTAS:Source"
[[node]]
name = "dst"
python = "IOTAS:{sink}"
[[bind]]
from = "src.out"
to = "{to}"
"""

FAN_IN = """{external}
[[node]]
name = "a"
python = "IOTAS:Source"
[[node]]
name = "b"
python = "IOTAS:Source"
[[node]]
name = "dst"
python = "IOTAS:{sink}"
[[bind]]
from = "a.out"
to = "dst.inp"
[[bind]]
from = "b.out"
to = "dst.inp"
"""



def ss(sink, to, external=""):
    return SOURCE_SINK.format(sink=sink, to=to, external=external)


def fan_in(sink):
    return FAN_IN.format(sink=sink, external="")


LONE_SINK = """{extra}
[[node]]
name = "dst"
python = "IOTAS:Sink"
"""

NODE = """
[[node]]
name = "dst"
python = "IOTAS:Sink"
external = ["dst.inp"]
"""

# (case, failing file, passing twin, words the error must contain)
CASES = [
    ("toml syntax", LONE_SINK.format(extra='external = ["dst.inp"'), LONE_SINK.format(extra='external = ["dst.inp"]'),
     "not valid TOML"),
    ("unknown key in [system]", LONE_SINK.format(extra='external = ["dst.inp"]\nextrnal = 1\n'),
     LONE_SINK.format(extra='external = ["dst.inp"]'), "unknown key 'extrnal'"),
    ("unknown node key", '[[node]]\nname = "dst"\npython = "IOTAS:Sink"\nrestrat = "always"\n'
     '[[bind]]\nfrom = "x.y"\nto = "dst.inp"', None, "unknown key 'restrat'"),
    ("no spec or python", '[[node]]\nname = "dst"\n', '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n',
     "exactly one of spec"),
    ("missing python file", '[[node]]\nname = "dst"\npython = "nope.py:Sink"\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n', "python file 'nope.py' not found"),
    ("python names a class that is no IOTA", '[[node]]\nname = "dst"\npython = "IOTAS:Input"\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n', "Input is a class but not an IOTA"),
    ("python names a module", '[[node]]\nname = "dst"\npython = "os:path"\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n', "'os:path': posixpath is a module, not an IOTA class"),
    # a function is called to build the IOTA, even by --check: only one annotated to return one
    ("python names a builtin", '[[node]]\nname = "dst"\npython = "os:system"\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n',
     "'os:system': builtin_function_or_method <built-in function system> is not an IOTA class"),
    ("python names a function that builds no IOTA", '[[node]]\nname = "dst"\npython = "shutil:rmtree"\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n',
     "rmtree is a function that does not say it returns an IOTA"),
    ("spec names a folder", '[[node]]\nname = "dst"\nspec = "."\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n', "spec file '.' is a folder; name the .iota file in it"),
    ("missing spec file", '[[node]]\nname = "dst"\nspec = "nope.iota"\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\n', "spec file 'nope.iota' not found"),
    ("bad restart", '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\nrestart = "sometimes"\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\nrestart = "always"\n', "restart must be one of"),
    ("bad max_restarts", '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\nmax_restarts = -1\n',
     '[[node]]\nname = "dst"\npython = "IOTAS:Stub"\nmax_restarts = 0\n', "max_restarts"),
    ("duplicate node", '[[node]]\nname = "d"\npython = "IOTAS:Stub"\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     '[[node]]\nname = "d"\npython = "IOTAS:Stub"\n[[node]]\nname = "e"\npython = "IOTAS:Stub"\n',
     "already [[node]] #1"),
    ("bad instance path", '[[node]]\nname = "a.b"\npython = "IOTAS:Stub"\n',
     '[[node]]\nname = "a/b"\npython = "IOTAS:Stub"\n', "instance path"),
    ("unknown param", '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nparams = { exit_cod = 1 }\n',
     '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nparams = { exit_code = 1 }\n', "cannot instantiate its IOTA"),
    ("after unknown node", '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nafter = ["x"]\n',
     '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nafter = []\n', "after names unknown node 'x'"),
    ("after in a circle", '[[node]]\nname = "a"\npython = "IOTAS:Stub"\nafter = ["c"]\n'
     '[[node]]\nname = "b"\npython = "IOTAS:Stub"\nafter = ["a"]\n[[node]]\nname = "c"\npython = "IOTAS:Stub"\nafter = ["b"]\n',
     '[[node]]\nname = "a"\npython = "IOTAS:Stub"\n'
     '[[node]]\nname = "b"\npython = "IOTAS:Stub"\nafter = ["a"]\n[[node]]\nname = "c"\npython = "IOTAS:Stub"\nafter = ["b", "a"]\n',
     "after goes round in a circle, so none of these could ever start: a -> c -> b -> a"),
    ("hosts on some nodes only", '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nhost = "a"\n'
     '[[node]]\nname = "e"\npython = "IOTAS:Stub"\n',
     '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nhost = "a"\n[[node]]\nname = "e"\npython = "IOTAS:Stub"\nhost = "b"\n',
     "every node names its host or none"),
    ("hub port out of range", '[system]\nname = "t"\n[system.endpoints]\nlisten = ["tcp/127.0.0.1:99999"]\n'
     '[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     '[system]\nname = "t"\n[system.endpoints]\nlisten = ["tcp/127.0.0.1:9999"]\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     "endpoints.listen: port out of range in 'tcp/127.0.0.1:99999' (0-65535)"),
    ("time_unit finer than recordings keep", '[system]\nname = "t"\ntime_unit = 1e-9\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     '[system]\nname = "t"\ntime_unit = 1e-6\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     "time_unit must be at least 1e-6 s"),
    ("start_gate not a boolean", '[system]\nname = "t"\nstart_gate = "no"\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     '[system]\nname = "t"\nstart_gate = false\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     "start_gate must be true or false, got 'no'"),
    ("start_gate in a node, not in [system]", '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nstart_gate = false\n',
     '[system]\nstart_gate = false\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n', "unknown key 'start_gate'"),
    ("bad time_unit", '[system]\nname = "t"\ntime_unit = 0\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n',
     '[system]\nname = "t"\ntime_unit = 0.001\n[[node]]\nname = "d"\npython = "IOTAS:Stub"\n', "time_unit"),
    ("bind unknown node", ss(sink="Sink", to="dts.inp"), ss(sink="Sink", to="dst.inp"),
     "no node named 'dts'"),
    ("bind unknown channel", ss(sink="Sink", to="dst.input"),
     ss(sink="Sink", to="dst.inp"), "has no external channel 'input'"),
    ("bind to an output", ss(sink="Sink", to="src.out"), ss(sink="Sink", to="dst.inp"),
     "is an output channel; expected an input"),
    ("index out of range", ss(sink="Fan", to="dst.inp[2]", external='external = ["dst.inp"]'),
     ss(sink="Fan", to="dst.inp[1]", external='external = ["dst.inp[0]"]'), "index 2 is out of range"),
    ("index on a plain channel", ss(sink="Sink", to="dst.inp[0]"),
     ss(sink="Sink", to="dst.inp"), "is not a family"),
    ("family to plain without index", ss(sink="Fan", to="dst.inp"),
     ss(sink="Fan", to="dst.inp[0]", external='external = ["dst.inp[1]"]'), "is a family of 2"),
    ("types differ", ss(sink="FloatSink", to="dst.inp"), ss(sink="Sink", to="dst.inp"),
     "types differ"),
    ("switching time", ss(sink="Sink", to="dst.inp").replace("IOTAS:Source", "IOTAS:FastSource"),
     ss(sink="FreeSink", to="dst.inp").replace("IOTAS:Source", "IOTAS:FastSource"),
     "would reject inputs (switching time)"),
    ("several senders", fan_in(sink="Sink"), fan_in(sink="FreeSink"), "has 2 senders"),
    ("unbound input", LONE_SINK.format(extra=""), LONE_SINK.format(extra='external = ["dst.inp"]'),
     "neither bound nor declared external"),
    ("family too large", 'external = ["d.inp"]\n[[node]]\nname = "d"\npython = "IOTAS:Fan"\nparams = { N = 100000 }\n',
     'external = ["d.inp"]\n[[node]]\nname = "d"\npython = "IOTAS:Fan"\nparams = { N = 100 }\n',
     "size of inp is 100000; a channel family has at most 10000 members"),
    ("many unbound members, the first listed", '[[node]]\nname = "d"\npython = "IOTAS:Fan"\nparams = { N = 40 }\n',
     'external = ["d.inp"]\n[[node]]\nname = "d"\npython = "IOTAS:Fan"\nparams = { N = 40 }\n',
     "d.inp[6], d.inp[7] and 32 more neither bound"),
    ("unbound family member", ss(sink="Fan", to="dst.inp[0]"),
     ss(sink="Fan", to="dst.inp[0]", external='external = ["dst.inp[1]"]'), "dst.inp[1] neither bound"),
    ("external names an output", LONE_SINK.format(extra='external = ["dst.inp", "dst.out"]'),
     LONE_SINK.format(extra='external = ["dst.inp"]'), "external[1]"),
]


@pytest.mark.parametrize("case, bad, good, words", CASES, ids=[c[0] for c in CASES])
def test_each_check_trips_and_its_twin_passes(tmp_path, case, bad, good, words):
    with pytest.raises(SystemFileError) as caught:
        load_system(write(tmp_path, bad))
    message = str(caught.value)
    assert words in message, message
    assert message.startswith("sys.toml: "), message  # every error names the file
    if good is not None:
        load_system(write(tmp_path, good, "good.toml"))


def test_error_names_the_entry(tmp_path):
    body = ss(sink="Sink", to="dst.inp") + '[[bind]]\nfrom = "src.outt"\nto = "dst.inp"\n'
    with pytest.raises(SystemFileError) as caught:
        load_system(write(tmp_path, body, "figure2.toml"))
    assert str(caught.value).startswith('figure2.toml: [[bind]] #2 (from="src.outt"): node \'src\' has no external')


def test_every_problem_is_listed(tmp_path):
    body = ss(sink="Sink", to="dst.nope") + '[[bind]]\nfrom = "nobody.out"\nto = "dst.inp"\n'
    with pytest.raises(SystemFileError) as caught:
        load_system(write(tmp_path, body))
    assert len(caught.value.errors) == 2, caught.value.errors


def test_a_node_that_cannot_be_built_is_one_problem_not_one_per_binding_or_bus(tmp_path):
    body = ss(sink="Sink", to="dst.inp").replace('python = "IOTAS:Source"', 'python = "IOTAS:Source"\nparams = { period = "x" }')
    body += ('[[node]]\nname = "ping"\npython = "IOTAS:CanPinger"\nparams = { period = "x" }\n'
             '[[node]]\nname = "echo"\npython = "IOTAS:CanEcho"\n'
             '[[can]]\nname = "can0"\ninterface = "virtual"\nchannel = "t"\nstations = ["ping", "echo"]\n')
    with pytest.raises(SystemFileError) as caught:
        load_system(write(tmp_path, body))
    # not also "node 'src' has no external channel 'out'", nor "station 'ping' needs ... can_tx"
    assert len(caught.value.errors) == 2, caught.value.errors
    assert all("cannot instantiate its IOTA" in error and "period" in error for error in caught.value.errors)


def test_figure2_configs_follow_the_node_host_contract():
    system = load_system(ROOT / "examples" / "figure2.toml")
    assert list(system.nodes) == ["scheduler", "vision", "manipulation"]
    config = system.node_config("scheduler", 123.5, ["tcp/127.0.0.1:7500"])
    assert config["inputs"] == {"req/0": ["iota/figure2/vision/req"], "req/1": ["iota/figure2/manipulation/req"]}
    assert config["connect"] == ["tcp/127.0.0.1:7500"] and config["origin"] == 123.5
    assert config["listen"] == ["tcp/127.0.0.1:0"]
    assert system.node_config("vision", 0.0, [])["inputs"] == {"ack": ["iota/figure2/scheduler/ack/0"]}
    from iotad.node_host.node_config import from_dict
    from_dict(config)  # the node host accepts it


def test_families_bind_element_wise(tmp_path):
    body = ('[[node]]\nname = "s"\npython = "IOTAS:Sources"\n[[node]]\nname = "f"\npython = "IOTAS:Fan"\n'
            '[[bind]]\nfrom = "s.out"\nto = "f.inp"\n')
    system = load_system(write(tmp_path, body))
    assert system.inputs_of("f") == {"inp/0": ["iota/t/s/out/0"], "inp/1": ["iota/t/s/out/1"]}


def test_hosts_and_hub(tmp_path):
    body = ('[system]\nname = "t"\nhub_host = "b"\n[system.endpoints]\nlisten = ["tcp/10.200.0.2:7447"]\n'
            '[hosts.a]\nlisten = ["tcp/10.200.0.1:0"]\n[hosts.b]\nlisten = ["tcp/10.200.0.2:0"]\n'
            '[[node]]\nname = "d"\npython = "IOTAS:Stub"\nhost = "a"\n'
            '[[node]]\nname = "e"\npython = "IOTAS:Stub"\nhost = "b"\n')
    system = load_system(write(tmp_path, body))
    assert [n.name for n in system.nodes_on("a")] == ["d"]
    assert system.opens_hub("b") and not system.opens_hub("a")
    assert system.node_config("d", 0.0, system.listen)["listen"] == ["tcp/10.200.0.1:0"]


def test_with_port():
    assert with_port(["tcp/127.0.0.1:7447", "tcp/[::1]:7447"], 9000) == ["tcp/127.0.0.1:9000", "tcp/[::1]:9000"]


def test_cli_check_exits_2_without_traceback(tmp_path):
    bad = write(tmp_path, ss(sink="FloatSink", to="dst.inp"))
    result = subprocess.run([sys.executable, "-m", "iotad", "run", "--check", str(bad)],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert "Traceback" not in result.stderr and "types differ" in result.stderr
    good = subprocess.run([sys.executable, "-m", "iotad", "run", "--check", str(ROOT / "examples" / "figure2.toml")],
                          capture_output=True, text=True, timeout=60)
    assert good.returncode == 0 and "ok" in good.stdout


ECHOES = """
[[node]]
name = "fast"
python = "{echo}:Echo"
params = {{ S = {sender} }}
[[node]]
name = "slow"
python = "{echo}:PacedEcho"
[[bind]]
from = "fast.out"
to = "slow.inp"
"""


def test_switching_times_that_name_a_parameter_are_checked_with_the_nodes_values(tmp_path):
    echo = ROOT / "examples" / "echo.py"
    ok = load_system(write(tmp_path, '[system]\nname = "t"\nexternal = ["fast.inp"]\n' + ECHOES.format(echo=echo, sender=1.0), "ok.toml"))
    assert ok.nodes["slow"].channels["inp"].switching_time == 1.0
    with pytest.raises(SystemFileError, match="may send every 0.5 time units"):
        load_system(write(tmp_path, '[system]\nname = "t"\nexternal = ["fast.inp"]\n' + ECHOES.format(echo=echo, sender=0.5), "bad.toml"))


def test_a_node_file_that_calls_sys_exit_as_it_loads_is_an_error_not_an_exit(tmp_path):
    (tmp_path / "exits.py").write_text("import sys\nsys.exit(3)\n")
    body = '[[node]]\nname = "d"\npython = "exits.py:Anything"\n'
    with pytest.raises(SystemFileError) as caught:  # not SystemExit: the CLI and the launcher go on
        load_system(write(tmp_path, body))
    assert "exits.py: it called sys.exit(3) as it loaded" in str(caught.value)


def test_a_node_file_that_calls_os_exit_as_it_loads_is_an_error_not_an_exit(tmp_path):
    """os._exit() cannot be caught: while a node file loads it raises instead. Checked in a
    process of its own, since a loader that let it through would end this one with status 0."""
    import subprocess
    import sys
    (tmp_path / "quits.py").write_text("import os\nos._exit(0)\n")
    path = write(tmp_path, '[[node]]\nname = "d"\npython = "quits.py:Anything"\n')
    probe = ("import os, sys\nfrom iotad.launcher.system.system_file import SystemFileError, load_system\n"
             "original = os._exit\ntry:\n    load_system(sys.argv[1])\nexcept SystemFileError as exc:\n"
             "    print(exc)\n    print('put back:', os._exit is original)\n    sys.exit(5)\n")
    done = subprocess.run([sys.executable, "-c", probe, str(path)], capture_output=True, text=True, timeout=60,
                          cwd=ROOT)
    assert done.returncode == 5, (done.returncode, done.stdout, done.stderr)
    assert "quits.py: it called os._exit(0) as it loaded" in done.stdout
    assert "put back: True" in done.stdout
