"""The engine sink: an in-process run (virtual time) recorded as a system of node hosts would
be, every event of a leaf on its `@trace` key and every output on its channel key
(`EngineRecorder`, `record_run`); `recording_header` is what it writes first, as plain data for a
writer in another process (`writer_process`)."""
from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any, Iterable

import msgpack

from iotad.node_host import wire
from iotad.recording.mcap_format import FORMAT_VERSION, format_name, json_default
from iotad.recording.mcap_sink import McapSink, schema_for_topic

_EVENT_KEYS = ("t", "iota", "action", "index", "kind", "value")  # an engine event's, in its order
_EVENT_HEAD = b"\x86\xa1t"  # msgpack: a map of 6, the key "t"
_VALUE_KEY = b"\xa5value"
_FLOAT64 = struct.Struct(">Bd").pack  # msgpack's float 64: 0xCB, big-endian double


def recording_header(root: Any, system: str | None = None, *, time_unit: float = 1.0, origin_ns: int = 0,
                     policy: Any = None, external: Iterable[str] = ()) -> dict[str, Any]:
    """What an `EngineRecorder` writes before the first event, as plain data (JSON and msgpack
    carry it as it is): the node paths, each node's spec, the recording's metadata and the
    system's description. A writer in another process starts from it (`writer_process`)."""
    from iotad.esprit.stored_spec import spec_record
    from iotad.kernel.compose import Composite, flatten
    flat = flatten(root)
    prefix = root.instance_name + "/"
    node_path = {}
    for leaf in flat.leaves:
        rel = leaf.path[len(prefix):] if leaf.path.startswith(prefix) else leaf.path
        node_path[leaf.path] = rel or leaf.path
    # each spec as its JSON text reads back: what the file holds, whichever process writes it
    specs = {node_path[leaf.path]: json.loads(json.dumps(spec_record(leaf.iota, node_path[leaf.path], time_unit),
                                                         default=json_default))
             for leaf in flat.leaves}
    name = system or root.instance_name
    bindings = [[str(s), str(d)] for s, d in flat.bindings]
    # a bus of format 1 (`CanBus`, one event per frame and receiver) makes the recording format 1
    version = min([getattr(leaf.iota, "recording_format", FORMAT_VERSION) for leaf in flat.leaves] + [FORMAT_VERSION])
    metadata = {"format": format_name(version), "system": name, "time_unit": time_unit, "origin_ns": origin_ns,
                "clock": "virtual", "writer": "EngineRecorder", "root": root.instance_name,
                "nodes": list(specs), "bindings": bindings, "composite": isinstance(root, Composite),
                **_policy_info(policy)}
    # `external`: the system file's external inputs ("motor.can_rx"), which the delivery check
    # judges as fed from outside (an input script's) rather than as a binding's
    described = {"name": name, "nodes": {p: {k: s[k] for k in ("source", "params")} for p, s in specs.items()},
                 "bindings": bindings, "external": list(external)}
    return {"system": name, "time_unit": time_unit, "origin_ns": origin_ns, "node_path": node_path,
            "specs": specs, "metadata": metadata, "system_json": described}


class EngineRecorder:
    """An Engine sink that writes what a system of node hosts would publish: every event of a
    leaf on `iota/<system>/<path>/@trace`, every output on its channel key. Virtual time `t`
    becomes log and publish time `t * time_unit` seconds after `origin_ns`."""

    def __init__(self, sink: McapSink, root: Any, system: str | None = None, *, time_unit: float = 1.0,
                 origin_ns: int = 0, policy: Any = None, external: Iterable[str] = ()):
        self._begin(sink, recording_header(root, system, time_unit=time_unit, origin_ns=origin_ns,
                                           policy=policy, external=external))

    @classmethod
    def from_header(cls, sink: McapSink, header: dict[str, Any]) -> "EngineRecorder":
        """The recorder of a system known only by its `recording_header` (no IOTAs here)."""
        recorder = cls.__new__(cls)
        recorder._begin(sink, header)
        return recorder

    def _begin(self, sink: McapSink, header: dict[str, Any]) -> None:
        self.sink = sink
        self.system, self.time_unit, self.origin_ns = header["system"], header["time_unit"], header["origin_ns"]
        self.node_path = header["node_path"]
        self._ids: dict[str, list] = {}  # topic -> [channel id, next sequence]
        self._specs: dict[str, dict] = header["specs"]
        self._cache: dict[str, dict] = {}
        for path, spec in self._specs.items():
            sink.add_spec(path, spec, self.origin_ns)
        sink.add_metadata("iotad.recording", header["metadata"])
        sink.attach("system.json", "application/json", json.dumps(header["system_json"], default=json_default).encode(),
                    self.origin_ns)
        self._writers()

    # The hot path (bench/worlds.py): per event, one dict look-up for its node's @trace topic (and
    # one for an output's key), one msgpack pack each (one Packer: the bytes of `packb`), and the
    # sink's fast writer, whose batch goes into the chunk every COMMIT_EVERY events and before a
    # new channel is registered, so the file keeps the order of `write` calls one by one.
    COMMIT_EVERY = 4096

    def _topic(self, topic: str) -> list:
        """[channel id, next sequence] of a topic, registered on first use."""
        state = self._ids.get(topic)
        if state is None:
            name, schema = schema_for_topic(topic, self._specs, self._cache)
            self._commit()  # the messages before it go first, as with one `write` at a time
            state = self._ids[topic] = [self.sink.channel(topic, name, schema), 0]
        return state

    def _writers(self) -> None:
        fast = getattr(self.sink, "fast_writer", None)
        self._write = fast() if fast is not None else self.sink.write
        self._write_pair = getattr(self.sink, "write_pair", None)
        self._commit = getattr(self.sink, "commit", lambda: None)
        self._pack = msgpack.Packer(use_bin_type=True).pack
        self._entries: dict[tuple, list] = {}  # (iota, channel, index, kind) -> `_entry`
        self._pending = 0

    def _entry(self, event: dict, key: tuple | None) -> list:
        """[its fields packed (None: not an engine's event), node path, @trace topic, output topic
        (None until the first output)] of an event's (iota, channel, index, kind); kept by `key`."""
        iota = event["iota"]
        path = self.node_path.get(iota, iota)
        trace = self._topic(wire.trace_key(self.system, path))
        middle = None
        if key is not None:
            middle = self._pack({"iota": path, "action": event["action"], "index": event["index"],
                                 "kind": event["kind"]})[1:] + _VALUE_KEY
        output = None
        if event["kind"] == "output":
            output = self._ids.get(wire.channel_key(self.system, path, event["action"], event["index"]))
        entry = [middle, path, trace, output]
        if key is not None:
            self._entries[key] = entry
        return entry

    def __call__(self, event: dict) -> None:
        if self._pending >= self.COMMIT_EVERY:
            self._commit()
            self._pending = 0
        self._pending += 1
        t = event["t"]
        ns = self.origin_ns + int(round(t * self.time_unit * 1e9))
        pack = self._pack
        value = pack(event.get("value"))
        kind = event["kind"]
        try:
            key = (event["iota"], event["action"], event["index"], kind)
            entry = self._entries.get(key)
        except TypeError:  # an unhashable field: not from an engine
            key = entry = None
        if entry is None:
            entry = self._entry(event, key)
        middle, path, trace, output = entry
        if middle is not None and tuple(event) == _EVENT_KEYS:
            # the bytes of pack(dict(event, iota=path)), its value packed once for both messages:
            # map header, "t", t, then iota/action/index/kind (packed once), "value", value
            data = b"".join((_EVENT_HEAD, _FLOAT64(0xCB, t) if t.__class__ is float else pack(t), middle, value))
        else:
            data = pack(dict(event, iota=path))
        seq = trace[1]
        trace[1] = seq + 1
        if kind != "output":
            self._write(trace[0], ns, ns, seq, data)
            return
        if output is None:  # the first output on this key: its trace event, then its channel
            self._write(trace[0], ns, ns, seq, data)
            output = entry[3] = self._topic(wire.channel_key(self.system, path, event["action"], event["index"]))
            sequence = output[1]
            output[1] = sequence + 1
            self._write(output[0], ns, ns, sequence, value)
            return
        sequence = output[1]
        output[1] = sequence + 1
        if self._write_pair is None:
            self._write(trace[0], ns, ns, seq, data)
            self._write(output[0], ns, ns, sequence, value)
        else:
            self._write_pair(trace[0], ns, ns, seq, data, output[0], ns, sequence, value)


def _policy_info(policy: Any) -> dict[str, Any]:
    """How the run chose firing times within windows (replay repeats an eager run by itself, and
    follows the recorded times of any other): {"policy": "eager"}, {"policy": "latest"},
    {"policy": "random", "seed": 7}, or a policy per node's own `info()` ("per-node", its default
    and its nodes' policies)."""
    info = getattr(policy, "info", None)
    if callable(info):
        return info()
    name = getattr(policy, "name", "eager")
    seed = getattr(policy, "seed", None)
    return {"policy": name} if seed is None else {"policy": name, "seed": seed}


def record_run(root: Any, output: str | Path, until: float, inputs: Iterable[dict] = (), policy: Any = None,
               system: str | None = None, **engine_options: Any):
    """Run `root` in virtual time up to `until` and write every event to `output` (an MCAP file).
    `inputs` are input-script entries (`iotad.kernel.input_script`). Returns the engine."""
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine
    sink = McapSink(output)
    try:
        recorder = EngineRecorder(sink, root, system, policy=policy)
        engine = Engine(root, VirtualClock(), policy, sinks=[recorder], **engine_options)
        for entry in inputs:
            if entry["t"] <= until:
                engine.post(entry.get("iota"), entry["action"], entry.get("value"), entry.get("index"), t=entry["t"])
        engine.run(until)
    finally:
        sink.finish()
    return engine
