"""The hub of a run under access control knows no password of another host's node: the Figure 2
split over two namespaces, started by one `iotad run --certs` on brain through arm's agent. arm's
node `vision` logs in to arm's router with a password the router made on arm; the hub's
credentials folder names no such user, and the agent kept its launcher's password alone. A third
namespace, with a certificate of the system's own authority and vision's real password (read from
arm's router's folder, as a thief on arm would), cannot open a session with the hub; the same
password opens one at arm's router, and the tools' credentials open the hub (the controls). Every
credentials folder is gone after the run."""
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from agent_helpers import Lines, authority_for, start
from launcher_helpers import ROOT
from namespaces import hosts, split_figure2

from iotad.launcher.processes import interrupt_then_kill

PORT = 7617
THIEF = r"""
import sys, zenoh
from iotad.machine import certificates
from iotad.node_host import credentials
from iotad.node_host.transport import open_session
hub, router, certs, vision, tools = sys.argv[1:6]
guest = certificates.host_files(certs, "guest")
for name, endpoint, given, files in (("hub with vision's password", hub, vision, guest),
                                     ("arm's router with vision's password", router, vision, None),
                                     ("hub with the tools' password", hub, tools, guest)):
    try:
        with open_session([], [endpoint], mode="client", connect_timeout=3, credentials=credentials.load(given),
                          tls=files):
            print(name, "OPENED")
    except zenoh.ZError:
        print(name, "refused")
"""


def test_a_node_password_of_another_host_does_not_open_the_hub(tmp_path):
    # arm's temporary folder, so that its agent's and its router's credentials are found, and only
    # this run's (a unix socket's path is short: not under pytest's long tmp_path)
    arm_tmp = Path(tempfile.mkdtemp(prefix="iotad-arm-", dir="/tmp"))
    try:
        with hosts("brain", "arm", "rogue", net=211) as net:
            hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
            certs = authority_for(tmp_path / "certs", {"brain": [hub], "arm": [arm], "guest": []})
            path = tmp_path / "split.toml"
            path.write_text(split_figure2("split", hub, PORT, "brain", "arm", arm, "tls", count=50))
            agent = start(net.exec("arm", "env", f"TMPDIR={arm_tmp}", sys.executable, "-m", "iotad", "agent",
                                   "--name", "arm", "--connect", f"tls/{hub}:{PORT}", "--certs", str(certs)))
            run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--plain", "--no-record",
                                 "--certs", str(certs)))
            run_lines = Lines(run)
            try:
                assert run_lines.wait_for("vision: live (on another host)", 90), run_lines.text()[-4000:]
                hub_folder = Path(re.search(r"credentials in (\S+),", run_lines.text()).group(1))
                hub_files = {p.name: p.read_text() for p in hub_folder.iterdir()}
                arm_folders = {p.parent for p in arm_tmp.glob("iotad-credentials-*/*.json")}
                arm_files = {p.parent.name + "/" + p.name for p in arm_tmp.glob("iotad-credentials-*/*")}
                visions = list(arm_tmp.glob("iotad-credentials-*/node-vision.json"))
                thief = subprocess.run(net.exec("rogue", sys.executable, "-c", THIEF, f"tls/{hub}:{PORT}",
                                                f"unixsock-stream/{visions[0].parent / 'router.sock'}" if visions else "",
                                                str(certs), str(visions[0]) if visions else "",
                                                str(hub_folder / "iotad-tools.json")),
                                       capture_output=True, text=True, timeout=60, cwd=ROOT)
            finally:
                code = interrupt_then_kill(run)
                interrupt_then_kill(agent)
        output = run_lines.text()
        assert code == 130 and "access control: on (" in output, output[-4000:]
        # the hub checks brain's node and arm's launcher, and knows nothing of arm's node
        users = {line.split(":", 1)[0] for line in hub_files["dictionary.txt"].splitlines()}
        assert {"node-scheduler", "iotad-launcher-arm", "iotad-agent-arm"} <= users, users
        assert not any("node-vision" in name or "node-vision" in text for name, text in hub_files.items())
        # on arm: the router's folder holds its node's password (beside its socket), the agent's its
        # launcher's alone
        assert len(visions) == 1, arm_files
        router_folder = visions[0].parent
        assert f"{router_folder.name}/router.sock" in arm_files, arm_files
        agent_folders = arm_folders - {router_folder}
        assert len(agent_folders) == 1, arm_files
        agent_folder = agent_folders.pop().name
        kept = {name.split("/", 1)[1] for name in arm_files if name.startswith(agent_folder + "/")}
        assert "iotad-launcher-arm.json" in kept and not any(name.startswith("node-") for name in kept), kept
        assert thief.stdout.splitlines() == ["hub with vision's password refused",
                                             "arm's router with vision's password OPENED",
                                             "hub with the tools' password OPENED"], thief.stdout + thief.stderr
        # every credentials folder went with the run: the hub's, the agent's and the router's
        assert not hub_folder.exists() and not list(arm_tmp.glob("iotad-credentials-*")), list(arm_tmp.iterdir())
    finally:
        shutil.rmtree(arm_tmp, ignore_errors=True)
