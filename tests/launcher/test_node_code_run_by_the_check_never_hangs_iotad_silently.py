"""`iotad run` and `iotad check` build every node in their own process to check it, which runs
the node's code. A node that starts a thread there (not a daemon) used to keep `iotad` from ever
exiting: Python waits for such threads; now iotad says so and exits with its own status. A node
whose code blocks there used to leave `iotad run` silent; now it is named after a while."""
import subprocess
import sys
from pathlib import Path

NODE = '''
import threading, time
from iotad import Int, Iota, Output

class Worker(Iota):
    out = Output(Int, switching=1)

    def init(self):
        threading.Thread(target=time.sleep, args=(3600,), name="worker").start()

    @out.action(value=lambda self: 1, after=1)
    def sent(self):
        pass
'''


def test_run_check_exits_and_names_the_thread(tmp_path):
    (tmp_path / "worker.py").write_text(NODE)
    system = tmp_path / "worker.toml"
    system.write_text('[system]\nname = "w"\n[[node]]\nname = "w"\npython = "worker.py:Worker"\n')
    done = subprocess.run([sys.executable, "-m", "iotad", "run", "--check", str(system)], capture_output=True,
                          text=True, timeout=60, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "not waiting for 1 thread(s) that a node's code started (worker)" in done.stderr
    bad = tmp_path / "bad.toml"  # the status is kept: an error still exits 2
    bad.write_text(system.read_text() + '[[bind]]\nfrom = "w.out"\nto = "nowhere.inp"\n')
    done = subprocess.run([sys.executable, "-m", "iotad", "run", "--check", str(bad)], capture_output=True,
                          text=True, timeout=60, cwd=tmp_path)
    assert done.returncode == 2 and "nowhere" in done.stderr, done.stderr


SLOW = '''
import time
from iotad import Int, Iota, Output

class Slow(Iota):
    out = Output(Int, switching=1)

    def init(self):
        time.sleep(1.0)  # a driver that takes its time: stands for one that blocks

    @out.action(value=lambda self: 1, after=1)
    def sent(self):
        pass
'''


def test_a_node_slow_to_build_is_named_while_iotad_waits(tmp_path, monkeypatch, capsys):
    """Building the nodes to check them runs their code; one that blocks there used to leave
    `iotad run` silent for ever. After SLOW_BUILD seconds it names the node."""
    from iotad.cli import main
    from iotad.launcher.system import system_file

    monkeypatch.setattr(system_file, "SLOW_BUILD", 0.2)
    (tmp_path / "slow.py").write_text(SLOW)
    system = tmp_path / "slow.toml"
    system.write_text('[system]\nname = "s"\n[[node]]\nname = "driver"\npython = "slow.py:Slow"\n')
    assert main(["run", "--check", str(system)]) == 0
    assert "still building node driver's IOTA to check it, after 0.2 s: its module or init may block" in \
        capsys.readouterr().err
