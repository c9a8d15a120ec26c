"""A run's summary shows a violation that several members of a family had at one instant once,
with the count and the indices ("x6 (i=0..5)"), not once per member: in real time (the
launcher's summary) and in one process (`iotad run --virtual`)."""
import sys

from iotad.cli import main
from iotad.launcher.options import LaunchOptions
from iotad.launcher.run.supervision import Launcher
from iotad.launcher.system.system_file import load_system
from launcher_helpers import IOTAS, free_port

MISS = {"kind": "violation", "t": 19.2022, "iota": "motor", "action": "arm",
        "value": {"violation": "deadline_miss", "message": "arm[i] fired at 19.2022, after its deadline 19.1961"}}


def a_launcher(tmp_path) -> Launcher:
    path = tmp_path / "s.toml"
    path.write_text(f'[system]\nname = "s"\n[system.endpoints]\nlisten = ["tcp/127.0.0.1:{free_port()}"]\n'
                    f'[[node]]\nname = "motor"\npython = "{IOTAS}:Rogue"\n')
    return Launcher(load_system(path), LaunchOptions(log_dir=str(tmp_path / "logs"), live_table=False))


def test_the_launchers_summary_groups_one_line_missed_by_six_axes(tmp_path):
    run = a_launcher(tmp_path)
    for index in range(6):
        run.tally.trace("motor", dict(MISS, index=index))
    run.tally.trace("motor", dict(MISS, t=20.5, index=2, value={"violation": "bad_value", "message": "out of range"}))
    summary = run.summary()
    misses = [line for line in summary if "after its deadline" in line]
    assert misses == ["    motor t=19.202: arm[i] fired at 19.2022, after its deadline 19.1961 x6 (i=0..5)"], summary
    assert "    motor t=20.500: out of range" in summary, summary
    assert any("violations: 7 (motor x7)" in line for line in summary), summary


def test_a_line_repeated_past_the_first_five_still_counts_and_leaves_room_for_others(tmp_path):
    run = a_launcher(tmp_path)
    for index in (0, 1, 3, 4, 5, 9):
        run.tally.trace("motor", dict(MISS, index=index))
    run.tally.trace("motor", dict(MISS, t=21.0, index=None, value={"violation": "zeno", "message": "a loop"}))
    summary = run.summary()
    assert "    motor t=19.202: arm[i] fired at 19.2022, after its deadline 19.1961 x6 (i=0,1,3..5,9)" in summary
    assert "    motor t=21.000: a loop" in summary, summary


FAILING = '''
from iotad import Int, Iota, Output

class Axes(Iota):
    """Six axes whose command fails alike at the same instant."""
    cmd = Output(Int, size=6)

    def init(self):
        self.sent = [False] * 6

    @cmd.action(value=lambda self, i: 1, when=lambda self, i: not self.sent[i], after=0.5)
    def cmd_sent(self, i):
        self.sent[i] = True
        raise ZeroDivisionError("division by zero")
'''


def test_the_virtual_runs_summary_groups_them_too(tmp_path, capsys):
    (tmp_path / "axes.py").write_text(FAILING)
    path = tmp_path / "axes.toml"
    path.write_text(f'[system]\nname = "axes"\n[[node]]\nname = "motor"\npython = "{tmp_path / "axes.py"}:Axes"\n')
    assert main(["run", str(path), "--virtual", "--until", "1", "--no-record"]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if "division by zero" in line]
    assert len(lines) == 1, out
    assert lines[0].endswith(" x6 (i=0..5)"), out


def test_violations_past_the_lines_shown_are_counted_and_the_summary_says_where_they_are(tmp_path):
    run = a_launcher(tmp_path)
    for k in range(8):  # eight distinct lines: five shown
        run.tally.trace("motor", dict(MISS, t=30.0 + k, index=None))
    run.tally.trace("motor", dict(MISS, t=37.0, index=None))  # the last one again: not shown either
    summary = run.summary()
    shown = [line for line in summary if "after its deadline" in line]
    assert len(shown) == 5, summary
    assert "    ... and 4 more, not shown here: a recording (-o FILE) would hold them" in summary, summary
    assert any("violations: 9 (motor x9)" in line for line in summary), summary


MANY = '''
from iotad import Int, Iota, Output

class Loud(Iota):
    """An output out of its range once a second: a distinct violation line each time."""
    out = Output(Int(0, 5))

    out.fires(value=lambda self: 10, within=(1, 1))
'''


def test_the_virtual_runs_summary_says_how_many_it_did_not_show_and_where_they_are(tmp_path, capsys):
    (tmp_path / "loud.py").write_text(MANY)
    path = tmp_path / "loud.toml"
    path.write_text(f'[system]\nname = "loud"\n[[node]]\nname = "n"\npython = "{tmp_path / "loud.py"}:Loud"\n')
    recording = tmp_path / "loud.mcap"
    assert main(["run", str(path), "--virtual", "--until", "8.5", "-o", str(recording)]) == 0
    out = capsys.readouterr().out
    assert len([line for line in out.splitlines() if line.startswith("  violation ")]) == 5, out
    assert f"  ... and 3 more, not shown here: 'iotad info {recording} --violations N' lists them" in out, out
    assert "8 violations" in out, out
    # ... and it does: each by its action and time, code and message (not the violation's dict)
    assert main(["info", str(recording), "--violations", "8"]) == 0
    listed = [line for line in capsys.readouterr().out.splitlines() if ": bad_value: " in line]
    assert listed == [f"    n: out at t={t}: bad_value: out: output value rejected: 10 outside range [0, 5]"
                      for t in range(1, 9)], listed
    assert main(["info", str(recording), "--violations", "2"]) == 0
    assert "    ... 6 more (--violations N lists more)" in capsys.readouterr().out
