"""A small system with a known timing bug, for the stress tests: `sender` pings within
[0.1, U] of its last ping (U = 0.6 by default), and `watchdog` counts a ping that comes more
than 0.5 s after the one before as late. Eager pings every 0.1 s and none is late; under
`latest` every ping is 0.6 s after the last and every one is late. Narrowing the sender's
window to U = 0.5 makes the spec keep the watchdog's word under every policy."""
from pathlib import Path

from iotad import Input, Int, Iota, Output, Param
from iotad.esprit.runtime import esprit_now


class Sender(Iota):
    U = Param(0.6)
    ping = Output(Int)

    def init(self):
        self.n = 0

    @ping.action(value=lambda self: self.n, within=(0.1, "U"))
    def sent(self):
        self.n += 1


class Watchdog(Iota):
    LIMIT = Param(0.5)
    ping = Input(Int)
    late = Output(Int)

    def init(self):
        self.last, self.count, self.pending = 0.0, 0, False

    @ping.input
    def got(self, n):
        now = esprit_now()
        if now - self.last > self.LIMIT:
            self.count += 1
        self.last, self.pending = now, True

    @late.action(value=lambda self: self.count, when=lambda self: self.pending, within=(0, 0.05))
    def said(self):
        self.pending = False


def watchdog_metrics(recording):
    said = [event["value"] for event in recording.trace() if event["kind"] == "output" and event["action"] == "late"]
    return {"late": said[-1] if said else 0, "pings": len(said)}


def write_system(folder: Path, window_end: float = 0.6) -> Path:
    here = Path(__file__).resolve()
    path = folder / "watchdog.toml"
    path.write_text(f'''[system]
name = "watchdog"

[[node]]
name = "sender"
python = "{here}:Sender"
params = {{ U = {window_end} }}

[[node]]
name = "watchdog"
python = "{here}:Watchdog"

[[bind]]
from = "sender.ping"
to = "watchdog.ping"

[sweep]
metrics = "{here}:watchdog_metrics"

[goals]
until = 10
late = "== 0"
pings = ">= 10"
violations = "== 0"
''')
    return path
