"""A process stopped by SIGINT while its main thread waits for the stop must stop.

The recorder (and the node host) set a `threading.Event` in their SIGINT handler and waited on it:
a signal that landed while the main thread was inside that Event's `wait()` ran the handler with
the Event's lock held, and `set()` waited for that lock for ever. A recorder whose launcher was
SIGKILLed hung so, an orphan with its file never finished (the once-failing
`test_sigkilled_launcher_leaves_no_orphans`). `iotad.node_host.stop_signals` takes no lock in the
handler. Each case runs in a process of its own: signals go to a main thread."""
import subprocess
import sys
import textwrap

import pytest

pytestmark = pytest.mark.timeout(120)

STORM = textwrap.dedent("""
    import os, signal, threading, time
    from {module} import {factory} as make
    stop = make()
    pid, end, sent = os.getpid(), time.monotonic() + 3.0, [0]

    def storm():  # SIGINT after SIGINT, each landing anywhere in the main thread's waiting
        while time.monotonic() < end:
            os.kill(pid, signal.SIGINT)
            sent[0] += 1
            time.sleep(0.00005)

    threading.Thread(target=storm, daemon=True).start()
    waits = stopped = 0
    while time.monotonic() < end:
        stopped += stop.wait(0.00001)
        waits += 1
        stop.received.clear()  # and wait again
    print("waits", waits, "stopped", stopped, "signals", sent[0])
""")


@pytest.mark.parametrize("module, factory", [
    ("iotad.recording.recorder_process", "stop_on_signals"),   # the recorder's stop
    ("iotad.node_host.stop_signals", "StopSignals"),                # the node host's
])
def test_a_storm_of_sigints_never_deadlocks_the_wait(module, factory):
    run = subprocess.run([sys.executable, "-c", STORM.format(module=module, factory=factory)],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr[-3000:]
    words = run.stdout.split()
    waits, stopped, signals = int(words[1]), int(words[3]), int(words[5])
    assert signals > 1000 and stopped > 100 and waits >= stopped, run.stdout


WAKE = textwrap.dedent("""
    import os, signal, threading
    from iotad.node_host.stop_signals import StopSignals
    stop = StopSignals()
    threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGTERM)).start()
    print("stopped", stop.wait(None), stop.received == [signal.SIGTERM])
""")


def test_a_signal_ends_a_wait_without_a_limit():
    """No polling: the signal's wake-up fd ends the wait (a missed wake-up would hang here)."""
    run = subprocess.run([sys.executable, "-c", WAKE], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and run.stdout.split() == ["stopped", "True", "True"], run.stdout + run.stderr
