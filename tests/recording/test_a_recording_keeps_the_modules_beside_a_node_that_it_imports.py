"""A Python node's recording stores the source of the modules beside it that it imports (the
conveyor's nodes import conveyor_geometry and conveyor_types from their folder), so that it is
checked and replayed by the code that ran: after that folder is gone (a check on another machine,
a worktree removed) or its modules were edited. A node whose stored code no longer builds is one
`NOT CHECKED` line; the other nodes are still judged."""
import json
import shutil
import sys
from pathlib import Path

from iotad.cli import main
from iotad.kernel.compose import Composite
from iotad.kernel.python_loader import load_object, neighbour_sources
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from recorded_systems import rewrite

ROOT = Path(__file__).resolve().parents[2]

NODE = '''
from iotad import Input, Int, Iota, Output
from steps import STEP


class Counter(Iota):
    go = Input(Int(0, None), switching=0)
    count = Output(Int(0, None), switching=0)

    def init(self):
        self.n, self.due = 0, False

    @go.input
    def went(self, times):
        self.n, self.due = self.n + STEP * times, True

    @count.action(value=lambda self: self.n, when=lambda self: self.due, within=(0, 0.1))
    def counted(self):
        self.due = False
'''
# steps imports a neighbour of its own: stored too
STEPS = "from units import UNIT\nSTEP = 2 * UNIT\n"
UNITS = "UNIT = 1\n"


def recorded(tmp_path) -> Path:
    folder = tmp_path / "robot"
    folder.mkdir()
    (folder / "counter_node.py").write_text(NODE)
    (folder / "steps.py").write_text(STEPS)
    (folder / "units.py").write_text(UNITS)
    counter = load_object(f"{folder}/counter_node.py:Counter")("counter")
    path = tmp_path / "run.mcap"
    record_run(counter, path, until=3.0, inputs=[{"t": 0.5, "action": "go", "value": 1}, {"t": 1.5, "action": "go", "value": 1}])
    return path


def check(path, capsys) -> tuple[int, str]:
    status = main(["check", str(path)])
    return status, capsys.readouterr().out


def test_a_node_is_checked_by_its_stored_neighbours_once_their_folder_is_gone(tmp_path, capsys):
    path = recorded(tmp_path)
    spec = read_recording(path).specs["counter"]
    assert spec["neighbours"] == {"steps": STEPS, "units": UNITS}
    counts = [e["value"] for e in read_recording(path).trace("counter") if e["action"] == "count"]
    assert counts == [2, 4]
    shutil.rmtree(tmp_path / "robot")
    status, out = check(path, capsys)
    assert status == 0 and "counter: 4 events, 2 firings checked, 0 problem(s)" in out, out
    assert main(["replay", str(path), "--node", "counter"]) == 0


def test_a_neighbour_edited_since_the_run_does_not_change_the_verdict(tmp_path, capsys):
    path = recorded(tmp_path)
    (tmp_path / "robot" / "units.py").write_text("UNIT = 5\n")  # the file on disk now says otherwise
    before = sys.modules.get("units")  # this process's own module of that name (the run imported it)
    status, out = check(path, capsys)
    assert status == 0 and "counter: 4 events, 2 firings checked, 0 problem(s)" in out, out
    assert sys.modules.get("units") is before  # left as it was


def test_a_recording_without_them_whose_neighbours_are_gone_says_so_for_that_node_and_judges_the_rest(
        tmp_path, capsys, monkeypatch):
    folder = tmp_path / "robot"
    path = recorded(tmp_path)
    # what a recording of an older iotad holds: the node's own text alone
    def older(name, data):
        if name != "spec/counter.json":
            return data
        spec = json.loads(data)
        del spec["neighbours"]
        return json.dumps(spec).encode()

    other = tmp_path / "other.mcap"
    record_run(Composite("both", load_object(f"{folder}/counter_node.py:Counter")("counter"),
                         load_object(f"{ROOT}/examples/requesters.py:Requester")("vision", epoch=1.0, timeout=2.0)),
               other, until=3.0, inputs=[{"t": 0.5, "iota": "both/counter", "action": "go", "value": 1}])
    older_file = rewrite(other, tmp_path / "older.mcap", attachment=older)
    shutil.rmtree(folder)
    # as in a fresh `iotad check` process: none of these modules imported, no other test's folder
    # on the path (where another steps.py may be)
    for name in ("steps", "units"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if not p.startswith(str(tmp_path.parent))])
    status, out = check(older_file, capsys)
    assert status == 1, out
    assert "counter: NOT CHECKED: " in out and "No module named 'steps'" in out, out
    assert "vision: 1 events, 1 firings checked, 0 problem(s)" in out, out  # the other node is still judged
    assert "check: PROBLEMS FOUND (1 node(s) not checked)" in out, out


def test_only_the_modules_beside_it_are_stored():
    found = neighbour_sources(ROOT / "examples" / "conveyor" / "manipulation.py")
    # its folder's modules, and theirs; packages (channels, iotad) and installed ones (numpy) are not
    assert set(found) == {"conveyor_geometry", "conveyor_types"}
    assert found["conveyor_geometry"] == (ROOT / "examples" / "conveyor" / "conveyor_geometry.py").read_text()
