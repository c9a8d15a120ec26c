"""Each layer of iotad imports only the layers below it (iotad/__init__.py lists them), and the
core never imports the robot packages built on it (channels, nodes, sim). Inside the launcher the
same holds for its packages by job (system, access, hosts, run; its own modules beside them,
the options and processes every part uses, import none of them); and a command of the CLI
imports no other command (what they share is in iotad.cli, the rest in the library)."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ["kernel", "esprit", "can", "ros2", "machine", "node_host", "launcher", "recording", "virtual", "sweep", "scaffold", "cli"]
ROBOT_PACKAGES = {"channels", "nodes", "sim"}
LAUNCHER_PARTS = ["system", "access", "hosts", "run"]  # each imports only those before it


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


def part_of(module: str) -> int | None:
    """The launcher package `module` is in, by its place in LAUNCHER_PARTS; -1 for a module of the
    launcher beside them; None outside the launcher."""
    parts = module.split(".")
    if parts[:2] != ["iotad", "launcher"] or len(parts) < 3:
        return None
    return LAUNCHER_PARTS.index(parts[2]) if parts[2] in LAUNCHER_PARTS else -1


def launcher_violations() -> list[str]:
    found = []
    for path in sorted((ROOT / "iotad" / "launcher").rglob("*.py")):
        name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        own = part_of(name)
        if own is None or name == "iotad.launcher.__init__":
            continue
        for module in imported_modules(path):
            other = part_of(module)
            if other is not None and other > own:
                where = LAUNCHER_PARTS[own] if own >= 0 else "beside the packages"
                found.append(f"{path.relative_to(ROOT)} ({where}) imports {module} ({LAUNCHER_PARTS[other]})")
    return found


def command_violations() -> list[str]:
    found = []
    for path in sorted((ROOT / "iotad" / "cli" / "commands").glob("*.py")):
        own = f"iotad.cli.commands.{path.stem}"
        for module in imported_modules(path):
            if module.startswith("iotad.cli.commands.") and not module.startswith(own):
                found.append(f"{path.relative_to(ROOT)} imports {module}")
    return found


def test_every_layer_imports_only_the_layers_below_it():
    assert violations() == []


def test_each_launcher_package_imports_only_those_below_it():
    assert launcher_violations() == []


def test_no_command_imports_another_command():
    assert command_violations() == []


def test_the_check_sees_an_upward_import(tmp_path, monkeypatch):
    # the checker itself must be able to fail: a kernel module importing the launcher is caught
    fake_root = tmp_path
    (fake_root / "iotad" / "kernel").mkdir(parents=True)
    (fake_root / "iotad" / "kernel" / "bad.py").write_text("def f():\n    from iotad.launcher.system import system_file\n")
    (fake_root / "iotad" / "kernel" / "rel.py").write_text("from ..recording import replay\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", fake_root)
    assert sorted(violations()) == [
        "iotad/kernel/bad.py (kernel) imports iotad.launcher.system (launcher)",
        "iotad/kernel/bad.py (kernel) imports iotad.launcher.system.system_file (launcher)",
        "iotad/kernel/rel.py (kernel) imports iotad.recording (recording)",
        "iotad/kernel/rel.py (kernel) imports iotad.recording.replay (recording)",
    ]


def test_the_check_sees_a_launcher_package_reaching_up(tmp_path, monkeypatch):
    (tmp_path / "iotad" / "launcher" / "system").mkdir(parents=True)
    (tmp_path / "iotad" / "launcher" / "system" / "model.py").write_text("def f():\n    from iotad.launcher.run import supervision\n")
    (tmp_path / "iotad" / "launcher" / "options.py").write_text("from iotad.launcher.access.policy import Grant\n")
    (tmp_path / "iotad" / "cli" / "commands").mkdir(parents=True)
    (tmp_path / "iotad" / "cli" / "commands" / "a.py").write_text("from .b import helper\n")
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    assert "iotad/launcher/system/model.py (system) imports iotad.launcher.run (run)" in launcher_violations()
    assert "iotad/launcher/options.py (beside the packages) imports iotad.launcher.access.policy (access)" \
        in launcher_violations()
    assert sorted(command_violations()) == ["iotad/cli/commands/a.py imports iotad.cli.commands.b",
                                            "iotad/cli/commands/a.py imports iotad.cli.commands.b.helper"]


def test_the_machine_layer_spells_the_key_prefix_as_the_wire_does():
    # clock_offset (iotad.machine, below the node host) cannot import the node host's wire
    from iotad.machine import clock_offset
    from iotad.node_host import wire

    assert clock_offset.PREFIX == wire.PREFIX
    assert clock_offset.clock_key("robot") == f"{wire.PREFIX}/robot/@clock"
