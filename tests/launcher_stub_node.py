"""A stand-in node host for launcher tests: reads the node config, waits `exit_after` seconds
and exits with `exit_code` (both from params), so restart policies can be tested exactly."""
import json
import sys
import time

config = json.load(open(sys.argv[1]))
time.sleep(float(config["params"].get("exit_after", 0.1)))
sys.exit(int(config["params"].get("exit_code", 0)))
