"""Owning processes: escalating stops, the parent-death signal, restart policy arithmetic."""
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from iotad.launcher.processes import Child, RestartPolicy, describe_exit
from launcher_helpers import wait_until


def gone(pid: int) -> bool:
    """True when no process `pid` runs (a zombie waiting for its reaper counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True


def python_child(tmp_path, name: str, code: str) -> Child:
    script = tmp_path / f"{name}.py"
    script.write_text(textwrap.dedent(code))
    return Child(name, [sys.executable, str(script)], log=tmp_path / f"{name}.log")


READY = """
import signal, sys, time
{ignore}
print("ready", flush=True)
time.sleep(60)
"""


def start_and_wait_ready(child: Child) -> None:
    child.start()
    assert wait_until(lambda: child.log.exists() and "ready" in child.log.read_text(), 10)


@pytest.mark.parametrize("ignore, expected", [
    ("", -signal.SIGINT),  # Python's default SIGINT handler raises KeyboardInterrupt: exit status 1
    ("signal.signal(signal.SIGINT, signal.SIG_IGN)", -signal.SIGTERM),
    ("signal.signal(signal.SIGINT, signal.SIG_IGN); signal.signal(signal.SIGTERM, signal.SIG_IGN)", -signal.SIGKILL),
], ids=["sigint", "sigterm", "sigkill"])
def test_stop_escalates(tmp_path, ignore, expected):
    child = python_child(tmp_path, "stubborn", READY.format(ignore=ignore))
    try:
        start_and_wait_ready(child)
        started = time.monotonic()
        code = child.stop(interrupt_timeout=0.5, terminate_timeout=0.5)
        took = time.monotonic() - started
        if expected == -signal.SIGINT:
            assert code in (1, -signal.SIGINT) and took < 0.5
        else:
            assert code == expected, describe_exit(code)
            assert took < 0.5 * (2 if expected == -signal.SIGKILL else 1) + 1.0
        assert gone(child.pid)
    finally:
        child.signal(signal.SIGKILL)


def test_children_have_their_own_process_group(tmp_path):
    child = python_child(tmp_path, "grouped", READY.format(ignore=""))
    try:
        start_and_wait_ready(child)
        assert os.getpgid(child.pid) == child.pid != os.getpgid(0)
    finally:
        child.stop(0.5, 0.5)


def test_exit_is_reported_at_once(tmp_path):
    exits = []
    child = python_child(tmp_path, "quick", "import sys; sys.exit(3)")
    child.on_exit = lambda c, code: exits.append((code, time.monotonic()))
    child.start()
    assert wait_until(lambda: exits, 10)
    assert exits[0][0] == 3 and child.code == 3


PARENT = """
import sys, time
sys.path.insert(0, {root!r})
from iotad.launcher.processes import Child
child = Child("sleeper", [sys.executable, "-c", "import time; time.sleep(60)"])
print(child.start(), flush=True)
time.sleep(60)
"""


def test_children_die_with_a_killed_parent(tmp_path):
    """PR_SET_PDEATHSIG through the exec wrapper: SIGKILL the parent, the child follows."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    parent = subprocess.Popen([sys.executable, "-c", PARENT.format(root=root)], stdout=subprocess.PIPE, text=True,
                              start_new_session=True)
    child_pid = None
    try:
        child_pid = int(parent.stdout.readline())
        assert not gone(child_pid)
        parent.kill()
        parent.wait(5)
        assert wait_until(lambda: gone(child_pid), 5), f"child {child_pid} survived its parent"
    finally:
        parent.kill()
        parent.wait(5)
        if child_pid and not gone(child_pid):
            os.kill(child_pid, signal.SIGKILL)


PARENT_SIGINT = """
import sys, time
sys.path.insert(0, {root!r})
from iotad.launcher.processes import Child
code = ("import signal, sys, time; signal.signal(signal.SIGINT, lambda *a: (print('interrupted', flush=True), "
        "sys.exit(0))); print('ready', flush=True); time.sleep(60)")
child = Child("recorder", [sys.executable, "-c", code], log={log!r}, death_signal=2)
print(child.start(), flush=True)
time.sleep(60)
"""


def test_a_child_may_be_interrupted_rather_than_killed_when_its_parent_dies(tmp_path):
    """The recorder's way: it gets SIGINT when the launcher is killed -9, and finishes its file."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    log = tmp_path / "recorder.log"
    parent = subprocess.Popen([sys.executable, "-c", PARENT_SIGINT.format(root=root, log=str(log))],
                              stdout=subprocess.PIPE, text=True, start_new_session=True)
    child_pid = None
    try:
        child_pid = int(parent.stdout.readline())
        assert wait_until(lambda: log.exists() and "ready" in log.read_text(), 10)  # its handler in place
        parent.kill()
        parent.wait(5)
        assert wait_until(lambda: gone(child_pid), 10), f"child {child_pid} survived its parent"
        assert "interrupted" in log.read_text()
    finally:
        parent.kill()
        parent.wait(5)
        if child_pid and not gone(child_pid):
            os.kill(child_pid, signal.SIGKILL)


def test_what_a_child_started_ends_when_it_ends(tmp_path):
    """A node that dies by itself leaves nothing behind: its process group is killed."""
    child = python_child(tmp_path, "parent", """
        import subprocess, sys, time
        grandchild = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
        print(grandchild.pid, flush=True)
        time.sleep(0.2)
        sys.exit(4)
        """)
    exits = []
    child.on_exit = lambda c, code: exits.append(code)
    child.start()
    assert wait_until(lambda: exits, 10) and exits == [4]
    grandchild = int(child.log.read_text().split()[0])
    assert wait_until(lambda: gone(grandchild), 5), f"grandchild {grandchild} outlived its parent"


def test_restart_policy():
    on_failure = RestartPolicy("on-failure", max_restarts=3, backoff=0.1)
    assert on_failure.wants_restart(1, 0) and on_failure.wants_restart(-9, 2)
    assert not on_failure.wants_restart(0, 0) and not on_failure.wants_restart(1, 3)
    assert RestartPolicy("always").wants_restart(0, 0)
    assert not RestartPolicy("never").wants_restart(1, 0)
    assert [on_failure.delay(k) for k in range(4)] == [0.1, 0.2, 0.4, 0.8]
    assert RestartPolicy(backoff=1.0, backoff_max=5.0).delay(10) == 5.0
