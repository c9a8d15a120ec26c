"""A real CAN bus through the `can_bus` fixture: python-can sends ODrive frames on the best tier
(vcan, user-mode Linux, udp_multicast) and iotad's bus receives them decoded equal; the command's
exit status comes back, a command past its time-out is killed with everything it started, and
Ctrl-C or SIGTERM to the wrapper is passed on to the command, which stops its own way."""
import json
import signal
import subprocess
import sys
import time

import pytest

from iotad.can import odrive, tiers
from iotad.can.frame import Frame

# Runs inside the tier: raw python-can sends, iotad.can.bus receives, and the reply goes back.
ROUND_TRIP = r'''
import json, os, sys
import can
from iotad.can.bus import open_env_bus
from iotad.can.frame import Frame

frames = [Frame(int(f["id"]), bytes.fromhex(f["data"]), rtr=f["rtr"]) for f in json.loads(sys.argv[1])]
interface, channel = os.environ["IOTAD_CAN_INTERFACE"], os.environ["IOTAD_CAN_CHANNEL"]
extra = {"port": 43113, "hop_limit": 1, "fd": False} if interface == "udp_multicast" else {}
raw = can.Bus(interface=interface, channel=channel, **extra)   # python-can itself, as a peer
with open_env_bus() as host:
    for frame in frames:
        raw.send(frame.to_can_message())
    got = [host.recv_frame(timeout=2.0) for _ in frames]
    got = [None if g is None else g[1] for g in got]
    host.send_frame(Frame(0x123, b"\x01\x02\x03"))
    reply = raw.recv(timeout=2.0)
    while reply is not None and reply.arbitration_id != 0x123:   # udp_multicast: raw hears itself
        reply = raw.recv(timeout=2.0)
    echo = host.recv(timeout=0.2)                               # its own frame never comes back
    echo = None if echo is None else Frame.from_can_message(echo)
raw.shutdown()
print("RESULT " + json.dumps({
    "tier": os.environ["IOTAD_CAN_TIER"], "interface": interface,
    "got": [None if f is None else {"id": f.id, "data": f.data.hex(), "rtr": f.rtr} for f in got],
    "reply": None if reply is None else [reply.arbitration_id, bytes(reply.data).hex()],
    "echo": None if echo is None else echo.id}))
'''


def odrive_frames():
    frames = [odrive.encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=0.2, Torque_FF=-0.05),
              odrive.encode(3, "Heartbeat", Axis_Error=odrive.AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"],
                            Axis_State=odrive.AXIS_STATE["IDLE"]),
              odrive.encode(7, "Get_Encoder_Estimates", Pos_Estimate=-2.25, Vel_Estimate=0.5),
              odrive.encode(1, "Estop"), odrive.encode(1, "Clear_Errors"),
              odrive.request(5, "Get_Error")]
    return frames


def round_trip(bus):
    frames = odrive_frames()
    payload = json.dumps([{"id": f.id, "data": f.data.hex(), "rtr": f.rtr} for f in frames])
    result = bus.run_python(ROUND_TRIP, payload, timeout=90).check()
    line = next(l for l in result.output.splitlines() if l.startswith("RESULT "))
    report = json.loads(line[len("RESULT "):])
    got = [Frame(f["id"], bytes.fromhex(f["data"]), rtr=f["rtr"]) for f in report["got"]]
    return frames, got, report


def test_python_can_round_trip_of_odrive_frames_on_the_best_tier(can_bus):
    frames, got, report = round_trip(can_bus)
    assert report["tier"] == can_bus.name and report["interface"] == can_bus.interface
    assert got == frames, f"tier {can_bus.name}"
    assert [odrive.decode(f) for f in got] == [odrive.decode(f) for f in frames]
    assert odrive.decode(got[0]).signals == {"Input_Pos": 1.5, "Vel_FF": 0.2, "Torque_FF": pytest.approx(-0.05)}
    assert report["reply"] == [0x123, "010203"]
    assert report["echo"] is None


@pytest.mark.skipif(tiers.why_not("udp_multicast") is not None, reason="no private network namespace here")
def test_the_udp_multicast_tier_filters_a_bus_s_own_frames():
    frames, got, report = round_trip(tiers.TierBus("udp_multicast"))
    assert report["tier"] == "udp_multicast" and got == frames and report["echo"] is None


def test_the_command_s_exit_status_and_output_come_back(can_bus):
    result = can_bus.run(["sh", "-c", 'echo "on $IOTAD_CAN_TIER $IOTAD_CAN_CHANNEL in $(pwd)"; exit 3'],
                         timeout=60, cwd="/tmp")
    assert result.returncode == 3
    assert result.output.strip() == f"on {can_bus.name} {can_bus.channel} in /tmp"
    with pytest.raises(RuntimeError, match=f"exited 3 in tier {can_bus.name}"):
        result.check()


def test_a_command_past_its_time_out_is_killed_with_what_it_started(can_bus, tmp_path):
    marker = tmp_path / "still-running"
    # a child that writes the marker 5 s after it starts, if it survived the kill at 4 s
    script = f"echo started; (sleep 5; touch {marker}) & sleep 60"
    with pytest.raises(tiers.TierTimeout) as info:
        can_bus.run(["sh", "-c", script], timeout=4)
    killed = time.monotonic()  # 4 s after the command began, 1 s before the child would write
    assert "ran past 4 s" in str(info.value) and f"tier {can_bus.name}" in str(info.value)
    assert "started" in info.value.run.output
    time.sleep(2.0)  # past when the child would have written
    assert not marker.exists(), killed


def test_the_timeout_counts_from_the_commands_start_not_the_tiers(can_bus):
    # user-mode Linux boots in about 2 s here, and far longer on a loaded machine: a command given
    # 1.5 s that needs 0.5 s runs to its end in every tier
    result = can_bus.run(["sh", "-c", "sleep 0.5; echo done"], timeout=1.5)
    assert result.returncode == 0 and result.output.strip() == "done"


def test_the_documented_command_says_which_tiers_this_host_has():
    done = subprocess.run([sys.executable, "-m", "iotad.can.tiers"], capture_output=True, text=True, timeout=60)
    lines = done.stdout.splitlines()
    assert [l.split()[0] for l in lines[:3]] == ["vcan", "uml", "udp_multicast"]
    best = tiers.best_tier().name
    assert lines[3].startswith(f"best: {best} (") and done.returncode == 0


def test_an_unknown_or_unavailable_tier_is_a_clear_error():
    with pytest.raises(tiers.TierUnavailable, match="unknown tier"):
        tiers.best_tier("can0")
    missing = [name for name, reason in tiers.available().items() if reason]
    for name in missing:
        with pytest.raises(tiers.TierUnavailable, match=f"CAN tier '{name}' cannot run here"):
            tiers.best_tier(name)


PANIC_CONSOLE = """SELinux:  Initializing.
mmapper_init - find_iomem failed
userspace - ptrace set fp regs failed, errno = 14
Kernel panic - not syncing: Attempted to kill init! exitcode=0x0000000b"""


def test_a_user_mode_kernel_that_cannot_boot_is_not_chosen_and_says_why(monkeypatch):
    """Installed is not enough: on a host CPU with AMX, Debian's 6.1 user-mode kernel panics at its
    first process. The probe boots it once; a panic names its cause (not the harmless lines
    before it), a hang is a time-out, and a kernel that boots is a tier."""
    def panics(*args):
        raise tiers.TierUnavailable("user-mode Linux did not report the command's exit status "
                                    f"(kernel exit -6, command never started)\n--- console ---\n{PANIC_CONSOLE}")
    monkeypatch.setattr(tiers, "_run_uml", panics)
    assert tiers._probe_uml() == ("user-mode Linux does not boot on this host "
                                  "(userspace - ptrace set fp regs failed, errno = 14)")

    def hangs(chosen, command, *args):
        raise tiers.TierTimeout("ran past", tiers.TierRun(chosen, command, -9, "", 60.0))
    monkeypatch.setattr(tiers, "_run_uml", hangs)
    assert tiers._probe_uml() == f"user-mode Linux did not boot within {tiers.UML_PROBE_TIMEOUT:g} s"

    def boots(chosen, command, *args):
        assert command == ["true"]
        return tiers.TierRun(chosen, command, 0, "", 2.0)
    monkeypatch.setattr(tiers, "_run_uml", boots)
    assert tiers._probe_uml() is None


# A command that stops its own way on SIGINT or SIGTERM (as `iotad run` does: stops its nodes,
# finishes its recording), and says how it stopped.
STOPS_ITS_OWN_WAY = r'''
import signal, sys, time
def stop(signum, frame):
    time.sleep(0.5)  # its own stop takes a while: the wrapper must wait for it
    open(sys.argv[1], "w").write(signal.Signals(signum).name)
    print("stopped by", signal.Signals(signum).name, flush=True)
    sys.exit(0)
signal.signal(signal.SIGINT, stop)
signal.signal(signal.SIGTERM, stop)
print("ready", flush=True)
time.sleep(60)
'''


@pytest.mark.parametrize("signum, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["SIGINT", "SIGTERM"])
def test_the_wrapper_passes_ctrl_c_and_sigterm_on_to_the_command(tmp_path, signum, status):
    how = tmp_path / "how"
    wrapper = subprocess.Popen([sys.executable, "-m", "iotad.can.tiers", "run", "--tier", "udp_multicast", "--",
                                sys.executable, "-c", STOPS_ITS_OWN_WAY, str(how)],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert wrapper.stdout.readline().strip() == "ready"
        wrapper.send_signal(signum)
        rest = wrapper.stdout.read()
        assert wrapper.wait(timeout=30) == status
    finally:
        if wrapper.poll() is None:
            wrapper.kill()
            wrapper.wait()
    # the command was told (not killed), stopped its own way, and its last words came through
    assert how.read_text() == signum.name
    assert f"stopped by {signum.name}" in rest
