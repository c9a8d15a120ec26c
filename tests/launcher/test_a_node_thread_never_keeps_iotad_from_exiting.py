"""`iotad run` and `iotad check` build every node in their own process to check it, which runs
the node's `init`. A node that starts a thread there (not a daemon) used to keep `iotad` from
ever exiting: Python waits for such threads. Now iotad says so and exits with its own status."""
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
