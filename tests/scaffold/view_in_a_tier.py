"""Run inside a CAN tier (tests/scaffold): a robot made by `iotad new` in real time with
`--view`, and a Foxglove WebSocket client (protocol foxglove.sdk.v1) that subscribes to the 3D
scene's joint states and prints, as one JSON line, the joint names and positions of the first
message it gets. argv: the robot's folder, the hub port, the view port."""
import base64
import json
import signal
import struct
import subprocess
import sys
import time

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from websockets.sync import client

folder, port, ws_port = sys.argv[1], sys.argv[2], int(sys.argv[3])
run = subprocess.Popen([sys.executable, "-m", "iotad", "run", "robot.toml", "--until", "120", "--after-live",
                        "--port", port, "--no-record", "--plain", "--view", str(ws_port)], cwd=folder)
result = {"error": "no joint states came"}
try:
    deadline = time.monotonic() + 100
    ws = None
    while ws is None and time.monotonic() < deadline:
        try:
            ws = client.connect(f"ws://127.0.0.1:{ws_port}", subprotocols=["foxglove.sdk.v1"], open_timeout=2)
        except OSError:
            time.sleep(0.5)
    with ws:
        channels, subscribed = {}, False
        while time.monotonic() < deadline:
            try:
                message = ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            if isinstance(message, str):
                body = json.loads(message)
                if body["op"] == "advertise":
                    channels.update({c["topic"]: c for c in body["channels"]})
                if body["op"] == "status" and body.get("level") == 2:
                    subscribed = False  # refused at once after the advertise (docs/watching.md): again
                if "/scene/arm_joints" in channels and not subscribed:
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": 1, "channelId": channels["/scene/arm_joints"]["id"]}]}))
                    subscribed = True
                continue
            channel = channels["/scene/arm_joints"]
            pool = descriptor_pool.DescriptorPool()
            for file in descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"])).file:
                pool.Add(file)
            cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
            decoded = cls.FromString(message[1 + struct.calcsize("<IQ"):])
            result = {"names": [j.name for j in decoded.joints], "positions": [j.position for j in decoded.joints]}
            break
finally:
    run.send_signal(signal.SIGINT)
    run.wait(60)
print("VIEWED " + json.dumps(result), flush=True)
