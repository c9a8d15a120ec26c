"""A recording holds its messages' times in whole nanoseconds, a trace event's `t` exactly. With
`time_unit = 0.001` (specs count milliseconds) a period of 0.3333333 ms falls between
nanoseconds: the check must pair each output with its message on the wire all the same."""
from pathlib import Path

from iotad.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_outputs_between_nanoseconds_are_delivered_as_sent(tmp_path, capsys):
    system = tmp_path / "ms.toml"
    system.write_text(f"""[system]
name = "ms"
time_unit = 0.001
external = ["b.reset", "b.inhibit"]

[[node]]
name = "b"
spec = "{ROOT / 'examples' / 'behaviours.iota'}"
params = {{ start = 0.3333333, period = 0.3333333, value = 3.0, step = 1.0, count = 20 }}
""")
    recording = tmp_path / "ms.mcap"
    assert main(["run", str(system), "--virtual", "--until", "0.01", "-o", str(recording)]) == 0
    capsys.readouterr()
    assert main(["check", str(recording)]) == 0
    report = capsys.readouterr().out
    assert "the wire holds 20 of 20 claimed messages as claimed" in report, report
