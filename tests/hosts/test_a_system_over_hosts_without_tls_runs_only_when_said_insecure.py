"""A system spread over hosts is secured by default: where its hosts could not be handed their
credentials safely (tcp/ links, no --certs, a launcher started by hand with --host) the run is
refused in one line that says what to do, before anything starts, unless --insecure says to run
it open; the agents of an open run start their launchers open too."""
import subprocess
import sys

from launcher_helpers import ROOT
from namespaces import split_figure2

from iotad.launcher.options import RunOptions
from iotad.launcher.run.run_system import fleet_for
from iotad.launcher.system.system_file import load_system


def iotad(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "iotad", *args], capture_output=True, text=True, timeout=60,
                          cwd=ROOT)


def system(tmp_path, scheme: str = "tcp"):
    path = tmp_path / "split.toml"
    # nothing is started: the addresses are the loopback's
    path.write_text(split_figure2("split", "127.0.0.1", 7691, "brain", "arm", "127.0.0.2", scheme=scheme))
    return path


def refusal(done: subprocess.CompletedProcess) -> str:
    assert done.returncode == 2, done.stdout + done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    return lines[0]


def test_the_hub_of_hosts_linked_by_tcp_refuses_to_run_open_unless_told(tmp_path):
    line = refusal(iotad("run", str(system(tmp_path)), "--until", "1", "--no-record"))
    assert "split spreads over hosts and its hub listens on tcp/127.0.0.1:7691" in line
    assert "access control would be off" in line
    assert "tls/ endpoints and give --certs DIR" in line and "--insecure" in line


def test_tls_links_without_certificates_are_refused_too(tmp_path):
    line = refusal(iotad("run", str(system(tmp_path, scheme="tls")), "--until", "1", "--no-record"))
    assert "its hub has no --certs DIR" in line and "--insecure" in line


def test_a_launcher_started_by_hand_without_the_hubs_credentials_is_refused(tmp_path):
    line = refusal(iotad("run", str(system(tmp_path)), "--host", "arm", "--until", "1", "--no-record"))
    assert line.startswith("iotad: error: --host arm: no credentials from the hub")
    assert "start this host through its agent" in line and "--insecure" in line


def test_check_says_when_such_a_run_is_refused(tmp_path):
    done = iotad("run", "--check", str(system(tmp_path)))
    assert done.returncode == 0, done.stderr
    assert "tcp/ links, and a --host launcher the hub's agent did not start, are refused without --insecure" \
        in done.stdout


def test_the_agents_of_an_open_run_start_their_launchers_open(tmp_path):
    loaded = load_system(system(tmp_path))
    options = RunOptions(agent_timeout=5)
    open_fleet, host = fleet_for(loaded, options, 7691, None, insecure=True)
    assert host == "brain" and all(order.insecure for order in open_fleet.host_orders.values())
    secured, _ = fleet_for(loaded, options, 7691, None)
    assert not any(order.insecure for order in secured.host_orders.values())
