"""A host whose router takes nothing more from the hub (a cut link: here the router's process
stopped, SIGSTOP, so that the link's buffers fill) does not stall the hub. The hub's own host's
node publishes its trace with congestion control BLOCK, as nodes do, and the router subscribes to
it (as every host's launcher does), so the hub forwards each message toward the stopped router
too. Once that link's queue is full, what the hub forwards there is dropped
(`host_access.across_hosts_settings`): the hub's own recorder hears every message while the router is
stopped, and the hub keeps its link to the router. Before, the message that found the queue full
waited on it on the hub's receive task of the node's link, and everything behind it with it, for
as long as zenoh's `wait_before_close` (docs/hosts.md, section 8): with it a minute long here, as
the lease is, the recorder heard 493 of the 4000 messages with one other host, and 3954 with two
(the node's own queue toward the stalled hub gave up the rest after its 5 s), within 20 s.

In both modes the hub runs in: a peer with one other host, a router with two (`zenoh_mode`).
On loopback, with the run's certificates and credentials. The lease is made a minute long, so that
the stopped router's silence does not close its link during the test, and so is the time a message
may wait on a full queue, so that a hub that waits there holds on for longer than the test waits
(with zenoh's 5 s it would give up and go on, only late)."""
import json
import signal
import subprocess
import sys
import threading

import pytest

from agent_helpers import authority_for
from launcher_helpers import IOTAS, ROOT, free_port, wait_until
from namespaces import hosts_header

from iotad.machine import certificates

from iotad.node_host import wire
from iotad.node_host.credentials import CredentialStore
from iotad.node_host.session_close import close_session
from iotad.node_host.transport import open_session
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.access.access_policy import RECORDER_USER, node_user
from iotad.launcher.access.host_access import launcher_user, router_zid, zenoh_mode
from iotad.launcher.system.system_file import load_system

import zenoh

# a minute for the lease, and for a message that waits on a full queue before zenoh gives it up
LONG = {"transport/link/tx/lease": 60000, "transport/link/tx/queue/congestion_control/block/wait_before_close": 60000000}
MESSAGES, SIZE = 4000, 8192  # 32 MB: far more than the loopback link's socket buffers hold


def system_file(tmp_path, port: int, third: bool):
    text = hosts_header("stall", "127.0.0.1", port, "brain", "arm", "127.0.0.1", "tls")
    nodes = [("tick", "brain"), ("beat", "arm")]
    if third:
        text += '[hosts.base]\nlisten = ["tls/127.0.0.1:0"]\n'
        nodes.append(("tock", "base"))
    for name, host in nodes:
        text += f'\n[[node]]\nname = "{name}"\nhost = "{host}"\npython = "{IOTAS}:Pulse"\n'
    path = tmp_path / "stall.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("third", [False, True], ids=["two hosts: the hub a peer", "three hosts: the hub a router"])
def test_a_host_router_that_takes_nothing_more_does_not_stall_the_hub(tmp_path, third):
    certs = authority_for(tmp_path / "certs", {host: ["127.0.0.1"] for host in ("brain", "arm", "base")})
    port = free_port()
    path = system_file(tmp_path, port, third)
    system = load_system(path)
    hub_endpoint = f"tls/127.0.0.1:{port}"
    hosts = ("arm", "base") if third else ("arm",)
    hub = AccessControl(system, hosts=hosts, certs=str(certs))
    received = CredentialStore([], passwords=hub.host_part("arm"))  # what arm's agent writes
    sessions, router = [], None
    try:
        options = hub.hub_options()
        assert options["mode"] == zenoh_mode(system) == ("router" if third else "peer")
        options["extra"].update(LONG)
        hub_session = open_session([hub_endpoint], [], tls=certificates.host_files(certs, "brain"), **options)
        sessions.append(hub_session)
        trace = wire.trace_key("stall", "tick")
        settings = [f"{key}={json.dumps(value)}" for key, value in LONG.items()]
        router = subprocess.Popen(
            [sys.executable, str(ROOT / "tests" / "router_child.py"), str(path), "arm",
             str(received.file_of(launcher_user("arm"))), str(certs), hub_endpoint, wire.every_node("stall", wire.TRACE),
             *settings], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, cwd=ROOT)
        lines: list[str] = []  # the router's lines, read as they come
        threading.Thread(target=lambda: lines.extend(iter(router.stdout.readline, "")), daemon=True).start()
        assert wait_until(lambda: any(line.startswith("zid ") for line in lines), 20), lines
        zid = next(line.split()[1] for line in lines if line.startswith("zid "))
        # the router takes the id the hub knows it by, from the password both hold
        assert zid == router_zid(received.credentials(launcher_user("arm")).password)

        def client(user: str):
            session = open_session([], [hub_endpoint], mode="client", connect_timeout=3, tls=certificates.host_files(certs, "brain"),
                                   credentials=hub.store.credentials(user))
            sessions.append(session)
            return session

        heard = []
        recorder = client(RECORDER_USER)
        payload = bytes(SIZE)
        # the messages of the stop alone (the first ones only made sure the router hears them)
        recorder.declare_subscriber(trace, lambda sample: heard.append(sample.payload.to_bytes())
                                    if len(sample.payload) == SIZE + 4 else None)
        node = client(node_user("tick"))
        publisher = node.declare_publisher(trace, congestion_control=zenoh.CongestionControl.BLOCK,
                                           priority=zenoh.Priority.DATA_LOW)

        def linked() -> bool:
            return zid in {str(z) for z in [*hub_session.info.routers_zid(), *hub_session.info.peers_zid()]}

        # the router hears the node's trace through the hub, so the hub forwards it there
        assert wait_until(linked, 20), "the router never linked to the hub"
        assert wait_until(lambda: publisher.put(b"x") or "heard\n" in lines, 20), lines
        router.send_signal(signal.SIGSTOP)
        for n in range(MESSAGES):
            publisher.put(n.to_bytes(4, "big") + payload)
        # the hub's recorder heard every message in order, and the hub never gave up on the router
        # (20 s: ample for 32 MB on loopback, and well short of the minute a held queue would wait)
        assert wait_until(lambda: len(heard) >= MESSAGES, 20), len(heard)
        assert [int.from_bytes(m[:4], "big") for m in heard] == list(range(MESSAGES))
        assert linked(), "the hub closed its link to the stopped router: a full queue held it"
    finally:
        if router is not None:
            router.send_signal(signal.SIGCONT)
            router.stdin.close()
            try:
                router.wait(15)
            except subprocess.TimeoutExpired:
                router.kill()
                router.wait()
        for session in reversed(sessions):  # a hub held by a full queue (the defect) closes late, if at all
            close_session(session, patience=15)
        received.remove()
        hub.close()
