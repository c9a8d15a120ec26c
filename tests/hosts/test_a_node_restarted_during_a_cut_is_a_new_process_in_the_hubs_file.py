"""A node killed and restarted by its host's launcher while its host is cut off from the hub, end
to end: brain (the hub) and arm in network namespaces, an open run recorded (`-o`), a pulse on
each host. arm's link is cut for longer than zenoh's lease; during the cut arm's pulse is killed
with SIGKILL and arm's launcher starts it again; then the link heals.

The hub's file alone holds neither the new process's start record nor its first events (nor the
launcher's `live` event of it), and the new process numbered its trace from 0 again. Its bursts
name the process that sent them, so the hub's recorder notes a new process, and `iotad check` of
the hub's file judges the old process up to its last event heard and says the restart: before,
it judged the new process's outputs against the old one's counter (`wrong_value`, `late`)."""
import os
import re
import signal
import subprocess
import sys
import threading
import time

from cut_recording import cut_a_while
from launcher_helpers import IOTAS, ROOT, wait_until
from namespaces import agent, hosts, hosts_header

from iotad.cli import main
from iotad.launcher.processes import interrupt_then_kill

PORT, NET = 7679, 221
CUT = 12.0  # s: past zenoh's lease (10 s): what arm's nodes send meanwhile never reaches the hub


def system_text(hub: str, arm: str) -> str:
    text = hosts_header("again", hub, PORT, "brain", "arm", arm)
    for name, host in (("tick", "brain"), ("beat", "arm")):
        text += f'\n[[node]]\nname = "{name}"\nhost = "{host}"\npython = "{IOTAS}:Pulse"\nparams = {{ period = 0.1 }}\n'
    return text


def test_a_node_restarted_during_a_cut_is_judged_as_a_new_process_from_the_hubs_file(tmp_path, capsys):
    hub_file = tmp_path / "again.mcap"
    with hosts("brain", "arm", net=NET) as net:
        hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        path = tmp_path / "again.toml"
        path.write_text(system_text(hub, arm))
        log = tmp_path / "run.log"
        with agent(net, "arm", f"tcp/{hub}:{PORT}", "--workdir", str(tmp_path / "agent")), log.open("w") as out:
            run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure",
                                            "--plain", "--until", "120", "-o", str(hub_file)),
                                   stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True)
            try:
                assert wait_until(lambda: run.poll() is not None or log.read_text().count("start gate open") == 2,
                                  90) and run.poll() is None, log.read_text()[-3000:]
                first = re.search(r"\[arm\] .*beat: started, pid (\d+)", log.read_text())
                assert first, log.read_text()[-3000:]

                def kill_during_the_cut() -> None:
                    # late in the cut: the new process has sent fewer trace events by the time the
                    # hub hears it again than the old one had, so its sequence numbers show no jump
                    # (the old recorder noted no gap at all, and the check judged it as the old one)
                    time.sleep(CUT - 2.0)
                    os.kill(int(first[1]), signal.SIGKILL)

                killer = threading.Thread(target=kill_during_the_cut, daemon=True)
                time.sleep(3.0)  # events of the first process heard before the cut
                killer.start()
                cut_a_while(net, CUT)
                killer.join()
                assert wait_until(lambda: "host arm: back" in log.read_text(), 60), log.read_text()[-3000:]
                # the new process's events reach the hub's recorder again (the launcher's lines say
                # so: it restarted beat during the cut, printed late)
                assert wait_until(lambda: re.search(r"\[arm\].*beat: restarted", log.read_text()), 30), \
                    log.read_text()[-3000:]
                time.sleep(3.0)  # outputs of the new process heard after the heal
                run.send_signal(signal.SIGINT)
                run.wait(60)
            finally:
                interrupt_then_kill(run)
    output = log.read_text()
    restarted = re.search(r"beat: restarted \(#1\), pid (\d+)", output)
    assert restarted, output[-3000:]
    code = main(["check", str(hub_file), "--all", "--no-delivery"])
    checked = capsys.readouterr().out
    lines = checked.splitlines()
    at = next(k for k, line in enumerate(lines) if line.startswith("beat: "))
    end = next((k for k in range(at + 1, len(lines)) if not lines[k].startswith("  ")), len(lines))
    beat = lines[at:end]
    gap = next((re.match(r"  GAP t=([\d.]+)\.\.([\d.]+): \d+ event\(s\) of its trace are not in this recording "
                         r"\(its process was restarted unheard: pid (\d+) started at t=([\d.]+)", line)
                for line in beat if line.startswith("  GAP")), None)
    assert gap and gap[3] == restarted[1], beat
    assert f"  restarted at t={gap[4]}: each run of its process is checked from its own start" in beat, beat
    # nothing of the new process judged against the old one's state: before, its outputs were
    # `wrong_value` (its counter from 0 again) and `late` (a window of the old process, open since
    # the cut). What the loaded machine made late before the cut, real timing, may be found.
    found = [(float(m[1]), m[2]) for m in (re.match(r"  t=([\d.]+) \[(\w+)\]", line) for line in beat) if m]
    assert all(t <= float(gap[1]) and problem == "late" for t, problem in found), beat
    assert "[wrong_value]" not in checked, checked[-3000:]
    assert code == 1, checked[-3000:]  # judged only up to the gap: no pass from the hub's file alone
