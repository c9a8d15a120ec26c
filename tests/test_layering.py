"""Each layer of iotad imports only the layers below it (iotad/__init__.py lists them), and the
core never imports the robot packages built on it (channels, nodes, sim)."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ["kernel", "esprit", "can", "ros2", "host", "launcher", "recording", "virtual", "sweep", "cli"]
ROBOT_PACKAGES = {"channels", "nodes", "sim"}


def imported_modules(path: Path) -> set[str]:
    """Absolute names of every module `path` imports, at any depth (function-level included)."""
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)
    return names


def layer_of(module: str) -> int | None:
    parts = module.split(".")
    if parts[0] != "iotad" or len(parts) < 2 or parts[1] not in LAYERS:
        return None
    return LAYERS.index(parts[1])


def violations() -> list[str]:
    found = []
    for path in sorted((ROOT / "iotad").rglob("*.py")):
        own = layer_of(".".join(path.relative_to(ROOT).with_suffix("").parts))
        for module in imported_modules(path):
            if module.split(".")[0] in ROBOT_PACKAGES:
                found.append(f"{path.relative_to(ROOT)} imports the robot package {module}")
            other = layer_of(module)
            if own is not None and other is not None and other > own:
                found.append(f"{path.relative_to(ROOT)} ({LAYERS[own]}) imports {module} ({LAYERS[other]})")
    return found


def test_every_layer_imports_only_the_layers_below_it():
    assert violations() == []


def test_the_check_sees_an_upward_import(tmp_path, monkeypatch):
    # the checker itself must be able to fail: a kernel module importing the launcher is caught
    fake_root = tmp_path
    (fake_root / "iotad" / "kernel").mkdir(parents=True)
    (fake_root / "iotad" / "kernel" / "bad.py").write_text("def f():\n    from iotad.launcher import system_file\n")
    (fake_root / "iotad" / "kernel" / "rel.py").write_text("from ..recording import replay\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", fake_root)
    assert sorted(violations()) == [
        "iotad/kernel/bad.py (kernel) imports iotad.launcher (launcher)",
        "iotad/kernel/bad.py (kernel) imports iotad.launcher.system_file (launcher)",
        "iotad/kernel/rel.py (kernel) imports iotad.recording (recording)",
        "iotad/kernel/rel.py (kernel) imports iotad.recording.replay (recording)",
    ]
