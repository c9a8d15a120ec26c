"""A node's stored `@spec` answer: made for an in-process IOTA (`spec_record`, what a node host
would answer), and the node rebuilt from one (`build_node`: its ESPRIT or Python text first, the
file it names only if there is no text). A recording keeps one per node, so that replay and check
need nothing but the recording. Here, beside the ESPRIT loader, because rebuilding needs both
loaders (this one and `iotad.kernel.python_loader`): the recording format does not import them.
"""
from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any

from iotad.esprit import load_iota, load_text
from iotad.kernel.model import param_values
from iotad.kernel.python_loader import LoadError, load_object, module_from_text, neighbour_sources, package_of
from iotad.kernel.types import to_plain


class StoredSpecError(Exception):
    """A stored spec that names no node this process can rebuild (one-line message)."""


def spec_record(iota: Any, path: str, time_unit: float = 1.0) -> dict:
    """The `@spec` answer for an in-process IOTA: what a node host would answer for it."""
    spec = iota.iota_spec
    if spec.source is not None:  # ESPRIT (or any spec that carries its text)
        source = {"kind": "esprit", "file": spec.source_path, "iota": spec.name}
        text = spec.source
    else:
        cls = type(iota)
        file = inspect.getsourcefile(cls)
        # the module's name too: a module of a package imports its neighbours relatively
        source = {"kind": "python", "ref": f"{file}:{cls.__name__}", "module": cls.__module__}
        text = Path(file).read_text() if file and Path(file).is_file() else None
    # a Python node's: the modules beside it that it imports (docs/internals.md, `neighbours`)
    neighbours = {"neighbours": neighbour_sources(file)} if source["kind"] == "python" and text is not None else {}
    return {"path": path, "source": source, "text": text, **neighbours, "params": to_plain(param_values(iota)),
            "channels": channel_list(spec, param_values(iota)), "time_unit": time_unit}


def channel_list(spec: Any, params: dict | None = None) -> list[dict]:
    """The channel table of an instance: switching times and sizes that name a parameter are
    resolved with `params` (as a node host's @spec answer gives them)."""
    params = {} if params is None else params
    return [{"name": c.name, "direction": c.direction, "type": None if c.type is None else c.type.name,
             "schema": None if c.type is None else c.type.json_schema(),
             "switching_time": spec.switching_of(c, params) if isinstance(c.switching_time, str) else c.switching_time,
             "size": spec.size_of(c, params) if isinstance(c.size, str) else c.size} for c in spec.channels.values()]


def build_node(spec: dict, name: str | None = None) -> Any:
    """Rebuild a node from its stored `@spec` answer (text first; the file only if no text)."""
    source = spec.get("source") or {}
    kind, params, text = source.get("kind"), dict(spec.get("params") or {}), spec.get("text")
    name = name or spec.get("path")
    if kind == "esprit":
        if text and source.get("file"):
            # the stored text under its file's name: externs named relative to the spec
            # ("buggy_math.py:wrap") resolve next to it, as when the node loaded it
            return load_text(text, str(source["file"])).factory(source.get("iota"))(name, **params)
        return load_iota(text if text else source["file"], iota=source.get("iota"), name=name, **params)
    if kind == "python":
        ref = source.get("ref", "")
        file, _, cls_name = ref.rpartition(":")
        if text:
            try:
                neighbours = spec.get("neighbours")
                module = module_from_text(text, file, package_of(source.get("module"), file),
                                          neighbours if isinstance(neighbours, dict) else None)
            except LoadError as exc:
                raise StoredSpecError(str(exc)) from None
            cls = getattr(module, cls_name, None)
            if cls is None:
                raise StoredSpecError(f"spec of {name}: its stored source has no {cls_name}")
        else:
            cls = load_object(ref)
        return cls(name, **params)
    raise StoredSpecError(f"spec of {name}: unknown source kind {kind!r}")
