"""Runs inside a CAN tier: `iotad run SYSTEM --until CAP --plain -o REC`; with `--kill-after K` it
kills the motor node with SIGKILL K seconds after it is live (its first life only), and it stops
the launcher (SIGINT) `--run-for R` seconds after the motor's last expected start is live (the
restart's, when it kills). Start-up under a busy user-mode kernel takes from 10 to 30 s, so times
count from what the launcher says, not from the start. Prints the launcher's lines as they come,
then `DRIVER {json}` with what it did.

    python tests/can_hil/arm_driver.py SYSTEM.toml REC.mcap --run-for 8 [--kill-after 2.5] [--until 200]
"""
import argparse
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LIVE = re.compile(r"^\[\s*([0-9.]+)\] motor: live \(pid (\d+)\)")


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("system")
    parser.add_argument("recording")
    parser.add_argument("--run-for", type=float, required=True)
    parser.add_argument("--until", type=float, default=200.0)
    parser.add_argument("--kill-after", type=float, default=None)
    args = parser.parse_args()
    iotad = str(Path(sys.executable).with_name("iotad"))
    launcher = subprocess.Popen([iotad, "run", args.system, "--until", str(args.until), "--plain",
                                 "-o", args.recording], cwd=ROOT, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, start_new_session=True)
    done = {"killed_pid": None, "killed_at": None, "lines": 0, "lives": 0, "stopped": False}
    timer = stopper = None
    lives_wanted = 1 if args.kill_after is None else 2

    def stop():
        done["stopped"] = True
        launcher.send_signal(signal.SIGINT)

    try:
        for line in launcher.stdout:
            sys.stdout.write(line)
            sys.stdout.flush()
            done["lines"] += 1
            live = LIVE.match(line)
            done["lives"] += bool(live)
            if live and done["lives"] == lives_wanted and stopper is None:
                stopper = threading.Timer(args.run_for, stop)
                stopper.start()
            if live and args.kill_after is not None and timer is None:
                pid = int(live.group(2))

                def kill(pid=pid):
                    os.kill(pid, signal.SIGKILL)
                    done["killed_pid"], done["killed_at"] = pid, time.time()
                    print(f"DRIVER killed motor pid {pid} with SIGKILL", flush=True)

                timer = threading.Timer(args.kill_after, kill)
                timer.start()
        code = launcher.wait(timeout=60)
    finally:
        for pending in (timer, stopper):
            if pending is not None:
                pending.cancel()
        if launcher.poll() is None:
            os.killpg(launcher.pid, signal.SIGKILL)
            launcher.wait()
    done["launcher_exit"] = code
    print("DRIVER " + json.dumps(done), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
