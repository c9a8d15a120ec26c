"""Code by content hash: an agent runs the hub's version of every file the system file names. A
file it holds at the hub's path with the same bytes is used there; one it lacks, or holds at
another version, is fetched from the hub by its sha256 into the agent's cache, and the system
file's declaration reads the name it writes as the cached file; bytes that do not hash to what the order names are refused, with a
clear error and no run. Checked on the files alone, through a real agent on loopback, and in
network namespaces where the agent's machine sees a stale checkout, over tcp and over TLS under
access control (the files then pass through the hub's policy)."""
import json
import os
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from agent_helpers import Lines, start
from launcher_helpers import ROOT, free_port
from namespaces import hosts, split_figure2
from iotad.machine import agent_secret, certificates
from iotad.launcher.hosts.code_by_hash import CodeCache, CodeError, localize, named_files, sha256_of
from iotad.launcher.system.declaration import read_declaration
from iotad.launcher.processes import interrupt_then_kill
from iotad.launcher.system.system_file import check_system

EXAMPLES = ROOT / "examples"


def hub_folder(tmp_path: Path) -> Path:
    """A hub's system file naming its nodes' code relative to itself, as a checkout would."""
    hub = tmp_path / "hub"
    (hub / "code").mkdir(parents=True)
    for name in ("scheduler.py", "requesters.py"):
        shutil.copy(EXAMPLES / name, hub / "code" / name)
    return hub


def system_text(hub_address: str, arm_address: str, scheme: str = "tcp", count: int = 2) -> str:
    return split_figure2("split", hub_address, 7625, "brain", "arm", arm_address, scheme, count=count).replace(f"{EXAMPLES}/", "code/")


def test_named_files_are_fetched_by_hash_only_where_this_machine_lacks_the_hubs_version(tmp_path):
    hub = hub_folder(tmp_path)
    system = hub / "split.toml"
    system.write_text(system_text("127.0.0.1", "127.0.0.2"))
    files = named_files(read_declaration(system))
    assert {f["written"] for f in files} == {"code/scheduler.py", "code/requesters.py"}
    served = {f["sha256"]: Path(f["path"]).read_bytes() for f in files}
    asked = []

    def fetch(sha):
        asked.append(sha)
        return served[sha]

    cache = CodeCache(tmp_path / "agent")
    # the same checkout: nothing fetched, the hub's own file runs
    here = {f["written"]: f["path"] for f in files}
    assert localize(files, cache, fetch) == (here, [])
    assert asked == []
    # this machine holds another version of the requester, and no scheduler at all
    hub_version = (hub / "code/requesters.py").read_bytes()
    (hub / "code/requesters.py").write_text("raise SystemExit('a stale copy')\n")
    (hub / "code/scheduler.py").unlink()
    replaced, said = localize(files, cache, fetch)
    assert sorted(asked) == sorted(served) and len(said) == 2
    assert any(line.startswith("code/requesters.py: another version is at") for line in said), said
    assert any(line.startswith("code/scheduler.py: no file is at") for line in said), said
    cached = cache.path_for(sha256_of(hub_version), "requesters.py")
    assert cached.read_bytes() == hub_version
    checked = check_system(read_declaration(system, files=replaced))  # its nodes load from the cache
    assert checked.nodes["vision"].source["ref"] == f"{cached}:Requester"
    assert checked.text == system.read_text()  # the hub's file as it is: no copy, no rewrite
    # once cached, a file is not fetched again
    asked.clear()
    assert localize(files, cache, fetch)[1] == []
    assert asked == []


def test_bytes_that_do_not_hash_to_the_named_sha256_are_refused(tmp_path):
    hub = hub_folder(tmp_path)
    system = hub / "split.toml"
    system.write_text(system_text("127.0.0.1", "127.0.0.2"))
    files = named_files(read_declaration(system))
    # the hub's paths do not exist on this machine
    files = [dict(f, path=str(tmp_path / "elsewhere" / f["written"])) for f in files]
    cache = CodeCache(tmp_path / "agent")
    with pytest.raises(CodeError, match=r"sha256 is [0-9a-f]{12}, not the [0-9a-f]{12} the run names: refused"):
        localize(files, cache, lambda sha: b"print('not the hub file')\n")
    assert not list(cache.folder.rglob("*.py"))  # nothing stored under any hash
    with pytest.raises(CodeError, match="not a node's .py or .iota file"):
        localize([{"written": "..", "path": "/x/..", "sha256": "ab" * 32}], cache, lambda sha: b"")
    with pytest.raises(CodeError, match="without its written name, path and sha256"):
        localize([{"written": "x.py", "path": "/x.py", "sha256": "../../etc"}], cache, lambda sha: b"")


def answer_of_a_real_agent(tmp_path: Path, serve_code) -> tuple[dict | None, list[str], object]:
    """A real agent on loopback, ordered to run a system whose files it lacks, by a hub session
    that answers `iota/@code/*` with `serve_code(query)` (None: nothing serves it): its answer,
    its lines and the agent."""
    from iotad.node_host.transport import open_session
    from iotad.launcher.hosts.agent import Agent
    from iotad.launcher.fleet_wire import agent_key, digest

    hub = hub_folder(tmp_path)
    system = hub / "split.toml"
    text = system_text("127.0.0.1", "127.0.0.2")
    system.write_text(text)
    files = [dict(f, path=str(tmp_path / "gone" / f["written"])) for f in named_files(read_declaration(system))]
    port = free_port()
    lines = []
    with open_session([f"tcp/127.0.0.1:{port}"], [], credentials=False) as session:
        served = session.declare_queryable("iota/@code/*", serve_code) if serve_code else None
        agent = Agent("arm", [f"tcp/127.0.0.1:{port}"], workdir=tmp_path / "agent", say=lines.append)
        serving = threading.Thread(target=agent.serve, daemon=True)
        serving.start()
        try:
            order = json.dumps({"system": text, "path": str(tmp_path / "gone" / "split.toml"), "digest": digest(text),
                                "files": files, "run": {}}).encode()
            answer = None
            deadline = time.monotonic() + 30
            while answer is None and time.monotonic() < deadline:
                for reply in session.get(f"{agent_key('arm')}/run", payload=order, timeout=15):
                    if reply.ok is not None:
                        answer = json.loads(reply.ok.payload.to_bytes())
                if answer is None:
                    time.sleep(0.2)  # the agent is not at the hub yet
        finally:
            agent.stop()
            serving.join(15)
            if served is not None:
                served.undeclare()
    return answer, lines, agent


def test_a_real_agent_refuses_a_run_whose_file_arrives_damaged(tmp_path):
    """The agent's wire: a hub that serves other bytes than the order's hash gets a refusal that
    says so, and the agent starts nothing."""
    answer, lines, agent = answer_of_a_real_agent(tmp_path, lambda q: q.reply(q.key_expr, b"# tampered\n"))
    assert answer is not None and answer["ok"] is False, answer
    assert "the run names: refused" in answer["error"], answer
    assert agent.child is None and any("refused a run" in line for line in lines), lines


def test_a_real_agent_that_nothing_serves_the_files_to_says_where_to_look(tmp_path):
    """A hub where nothing serves `iota/@code/*` to the agent (under access control: a policy
    that does not let it ask, or the fleet serve) answers at once with no file: the refusal says
    so, instead of a wait that never happened."""
    answer, lines, agent = answer_of_a_real_agent(tmp_path, None)
    assert answer is not None and answer["ok"] is False, answer
    assert "nothing there serves iota/@code/* to this agent (under access control" in answer["error"], answer
    assert agent.child is None and any("refused a run" in line for line in lines), lines


STALE_CHECKOUT = r"""
set -e
code="$1"; shift
mount -t tmpfs tmpfs "$code"
printf 'raise SystemExit("a stale copy of the scheduler")\n' > "$code/scheduler.py"
exec "$@"
"""


def stale_agent(net, hub: Path, tmp_path: Path, connect: str, *options: str) -> subprocess.Popen:
    """The arm's agent, in a mount namespace of its own where the hub's code folder is a stale
    checkout: a scheduler.py that would not load, no requesters.py."""
    return subprocess.Popen(net.exec("arm", "unshare", "--mount", "--propagation", "private", "sh", "-c",
                                     STALE_CHECKOUT, "stale", str(hub / "code"), sys.executable, "-m", "iotad",
                                     "agent", "--name", "arm", "--connect", connect,
                                     "--workdir", str(tmp_path / "agent"), *options),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                            start_new_session=True)


def skip_without_unshare() -> None:
    if shutil.which("unshare") is None:
        pytest.skip("needs unshare (util-linux) to give the agent a mount namespace of its own")


def skip_where_mounts_are_refused(agent_output: str) -> None:
    if "mount: " in agent_output and "permission denied" in agent_output.lower():
        pytest.skip(f"cannot mount in a namespace here: {agent_output[:300]}")


def assert_the_hubs_files_ran(stdout: str, hub: Path, tmp_path: Path) -> None:
    """The run's lines say the arm fetched both files by hash and its requester ran; the agent's
    cache holds the hub's bytes under their hashes."""
    assert "host arm: its agent runs its nodes" in stdout and "COMMIT" in stdout, stdout[-3000:]
    assert f"host arm: code/scheduler.py: another version is at {hub}/code/scheduler.py here; " \
           "fetched sha256" in stdout, stdout[-3000:]
    assert f"host arm: code/requesters.py: no file is at {hub}/code/requesters.py here; " \
           "fetched sha256" in stdout, stdout[-3000:]
    assert re.search(r"\[arm\] .*vision: live \(pid", stdout), stdout[-3000:]
    for name in ("scheduler.py", "requesters.py"):  # cached by hash, the hub's bytes
        data = (hub / "code" / name).read_bytes()
        assert (tmp_path / "agent" / "code" / sha256_of(data) / name).read_bytes() == data


def test_an_agent_whose_checkout_is_stale_runs_the_hubs_files(tmp_path):
    """In namespaces: the arm's machine sees the hub's code folder as its own stale checkout (a
    scheduler.py that would not load, no requesters.py). Its agent fetches both by hash and the
    split Figure 2 run commits as with a checkout of the same revision."""
    skip_without_unshare()
    hub = hub_folder(tmp_path)
    with hosts("brain", "arm", net=206) as net:
        address = net.addresses[("brain", "arm")]
        system = hub / "split.toml"
        system.write_text(system_text(address, net.addresses["arm"]))
        agent = stale_agent(net, hub, tmp_path, f"tcp/{address}:7625")
        run = watch = None
        try:
            # the scheduler's first answer to the arm's requester (a COMMIT), however long start-up
            # takes: watched from before the hub opens (the watcher waits for it)
            watch = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "echo", "iota/split/scheduler/ack/0",
                                              "--count", "1", "--timeout", "90", "--connect-timeout", "60",
                                              "--connect", f"tcp/{address}:7625"),
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                                     start_new_session=True)
            log = tmp_path / "run.log"
            with log.open("w") as out:
                run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(system), "--insecure", "--plain",
                                                "--no-record"),
                                       stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True)
            answered = watch.communicate(timeout=150)[0]
            code_of_run = interrupt_then_kill(run)
        finally:
            for process in (watch, run):
                if process is not None:
                    interrupt_then_kill(process)
            code = interrupt_then_kill(agent)
            output = agent.stdout.read()
        stdout = log.read_text()
        skip_where_mounts_are_refused(output)
        assert watch.returncode == 0, answered + stdout[-3000:] + output[-2000:]
        assert code_of_run == 130, stdout[-3000:]  # stopped by the test's Ctrl-C, after the answer
        assert_the_hubs_files_ran(stdout, hub, tmp_path)
        assert code == 0, output


def test_an_agent_whose_checkout_is_stale_runs_the_hubs_files_under_access_control(tmp_path):
    """The same stale checkout, with the run over TLS under access control (`--certs`): the
    agent, admitted as the arm's agent, asks the hub's fleet session for the files by hash
    through the hub's policy, and the requester's answer (a COMMIT) reaches a reader holding
    the tools' credentials."""
    skip_without_unshare()
    hub = hub_folder(tmp_path)
    certs = tmp_path / "certs"
    with hosts("brain", "arm", net=206) as net:
        address, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        certificates.init_authority(certs)
        for host, addresses in (("brain", [address]), ("arm", [arm])):
            certificates.issue_host(certs, host, addresses)
            agent_secret.write(certs, host)  # as 'iotad certs host' does
        system = hub / "split.toml"
        # requests keep coming until the test's Ctrl-C: the reader, started once the hub opens,
        # hears a COMMIT however late it subscribes
        system.write_text(system_text(address, arm, "tls", count=1000))
        agent = stale_agent(net, hub, tmp_path, f"tls/{address}:7625", "--certs", str(certs))
        run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(system), "--plain", "--no-record",
                             "--certs", str(certs)))
        agent_lines, run_lines, watch = Lines(agent), Lines(run), None
        try:
            assert run_lines.wait_for("credentials in ", 90), run_lines.text()[-3000:]
            # the scheduler's answers, read as docs/hosts.md says a tool does: the host's
            # certificate and the run's tools' credentials (the policy's read-only user)
            tools = re.search(r"credentials in (\S+),", run_lines.text()).group(1) + "/iotad-tools.json"
            watch = start(net.exec("brain", sys.executable, "-m", "iotad", "echo", "iota/split/scheduler/ack/0",
                                   "--count", "1", "--timeout", "90", "--connect-timeout", "30",
                                   "--connect", f"tls/{address}:7625"),
                          env=dict(os.environ, IOTAD_CERTS=str(certs), IOTAD_CERTS_HOST="brain",
                                   IOTAD_CREDENTIALS=tools))
            watch_lines = Lines(watch)
            # until the answer, or until the run or the reader ends without it (a refused part)
            while not watch_lines.wait_for("COMMIT", 1.0) and run.poll() is None and watch.poll() is None:
                pass
        finally:
            code_of_run = interrupt_then_kill(run)
            if watch is not None:
                interrupt_then_kill(watch)
            code = interrupt_then_kill(agent)
        stdout, said = run_lines.text(), agent_lines.text()
        skip_where_mounts_are_refused(said)
        answered = watch_lines.text()
        assert watch.returncode == 0 and "COMMIT" in answered, answered + stdout[-3000:] + said[-2000:]
        assert code_of_run == 130, stdout[-3000:]  # stopped by the test's Ctrl-C, after the answer
        assert "access control: on (" in stdout and "access control is OFF" not in stdout, stdout[-3000:]
        assert "agent arm: ready at the hub (admitted as iotad-agent-arm)" in said, said
        assert_the_hubs_files_ran(stdout, hub, tmp_path)
        assert code == 0, said
