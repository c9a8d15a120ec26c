"""The pictures of a real-time run whose world node was restarted (killed, then started again by
the launcher): the restarted world begins from a new world, so the Buggy path is not joined
across the restart and its landmarks are not drawn twice, and the conveyor's counts go on from
where the first world's ended instead of dropping back to 0; the restart is marked."""
from iotad.node_host import wire
from sim.worlds.buggy_plot import _runs, buggy_data, plot
from sim.worlds.conveyor_plot import _across_restarts
from iotad.recording.mcap_reader import read_recording
from iotad.recording.mcap_sink import McapSink

CRACK = {"kind": "CRACK", "id": 0, "x1": -1.0, "y1": 0.0, "x2": 1.0, "y2": 0.5}
WALL = {"kind": "WALL", "id": 0, "x1": -2.0, "y1": -2.0, "x2": 2.0, "y2": 2.0}


def event(node, t, kind, action, value=None):
    return {"t": t, "iota": node, "action": action, "index": None, "kind": kind, "value": value}


def buggy_recording(path):
    """body runs from t=0, dies after t=4, and runs again from t=5 (from the start pose)."""
    sink = McapSink(path)
    sink.add_metadata("iotad.recording", {"system": '"b"', "clock": '"real"'})
    channels = {n: sink.channel(wire.trace_key("b", n), "iotad.trace_event", {}) for n in ("body", "buggy")}
    events = []
    for start in (0.0, 5.0):  # each run of the world says its landmarks, then moves from the start
        events.append(("body", event("body", start, "start", "@start", {"wall": 100.0 + start, "pid": 1 + int(start)})))
        events += [("body", event("body", start + 0.01, "output", "landmark", mark)) for mark in (WALL, CRACK)]
        events += [("body", event("body", start + k * 0.5, "output", "pose",
                                  {"x": 0.1 * k, "y": 0.0, "yaw": 0.0, "bumps": k // 4})) for k in range(1, 9)]
    events += [("buggy", event("buggy", 0.5 * k, "output", "mood", {"hunger": 0.1, "fear": 0.0, "doing": "WANDER"}))
               for k in range(1, 20)]
    for seq, (node, e) in enumerate(sorted(events, key=lambda item: item[1]["t"])):
        ns = int(e["t"] * 1e9) + 1
        sink.write(channels[node], ns, ns, seq, wire.encode(e))
    sink.finish()
    return read_recording(path)


def test_buggy_path_is_cut_at_the_restart_and_its_landmarks_are_drawn_once(tmp_path):
    recording = buggy_recording(tmp_path / "b.mcap")
    data = buggy_data(recording)
    assert recording.restart_times("body") == [5.0] and data["restarts"] == [5.0] and data["world"] == "body"
    assert len(data["arena"]["cracks"]) == 1  # said twice, one crack
    runs = _runs(data["path"], data["restarts"])
    assert [len(run) for run in runs] == [8, 8] and runs[1][0][1]["x"] == 0.1  # the new world's start
    picture = plot(recording, tmp_path / "b.png")
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_conveyor_counts_go_on_across_a_restart_of_its_world():
    def counts(spawned, placed, held):
        return {"spawned": spawned, "placed": placed, "missed": 0, "dropped": 0, "held": held}

    tally = [(1.0, counts(1, 0, 0)), (4.0, counts(2, 1, 1)),        # the first world: 2 seen, 1 placed
             (6.0, counts(0, 0, 0)), (9.0, counts(1, 1, 0))]         # a new world from t=5
    whole = _across_restarts(tally, [5.0])
    assert [(t, c["spawned"], c["placed"], c["held"]) for t, c in whole] == [
        (1.0, 1, 0, 0), (4.0, 2, 1, 1), (6.0, 2, 1, 0), (9.0, 3, 2, 0)]
    assert _across_restarts(tally[:2], []) == tally[:2]  # no restart: the counts as they are
