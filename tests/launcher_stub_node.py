"""A stand-in node host for launcher tests, playing a node exactly as its params say:

- exit_after, exit_code: wait, then exit with that status (restart policies, tested exactly);
- stderr: a line printed on stderr first (what a failing node says);
- ignore_signals: shrug off SIGINT and SIGTERM (only SIGKILL ends it);
- token: join the system's zenoh hub and declare the node's liveliness token;
- beat: then also publish heartbeats (without: a node frozen before its first heartbeat);
- flood_hz: publish 0, 1, 2... on the node's `out` key at that rate, past any switching time.
"""
import json
import signal
import sys
import time

config = json.load(open(sys.argv[1]))
params = config["params"]
if params.get("ignore_signals"):
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)
if params.get("stderr"):
    print(params["stderr"], file=sys.stderr, flush=True)
session = None
if params.get("token") or params.get("flood_hz"):
    from iotad.node_host import wire
    from iotad.node_host.transport import open_session

    session = open_session(config["listen"], config["connect"])
base = f"iota/{config['system']}/{config['path']}"
try:
    # kept in a name: a token that is garbage-collected is undeclared
    token = session.liveliness().declare_token(f"{base}/@alive") if params.get("token") else None
    beat = session.declare_publisher(f"{base}/@heartbeat") if params.get("beat") else None
    out = session.declare_publisher(f"{base}/out") if params.get("flood_hz") else None
    print("ready", flush=True)
    beat_period = float(config.get("heartbeat_period", 0.2))
    started = next_beat = time.monotonic()
    deadline = started + float(params.get("exit_after", 0.1))
    sent = 0
    while (now := time.monotonic()) < deadline:
        if beat is not None and now >= next_beat:
            beat.put(wire.encode({"t": now - started, "firings": sent, "queue": 0}))
            next_beat = now + beat_period
        wake = now + 0.05
        if out is not None:
            out.put(wire.encode(sent), attachment=wire.encode_attachment(sent))
            sent += 1
            wake = started + sent / params["flood_hz"]
        if beat is not None:
            wake = min(wake, next_beat)
        time.sleep(max(0.0, min(wake, deadline) - time.monotonic()))
finally:
    if session is not None:
        session.close()
sys.exit(int(params.get("exit_code", 0)))
