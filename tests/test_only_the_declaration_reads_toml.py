"""The declaration (iotad/launcher/system/declaration.py) is the one reader of a system file's
TOML: every other part of iotad takes the declaration, or the system checked from it, so that a
key is read, checked and named in error messages in one place. No other module of iotad imports a
TOML parser, at any depth (inside functions too)."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOML_PARSERS = {"tomllib", "tomli", "toml", "tomlkit", "pytoml", "rtoml"}
READER = "iotad/launcher/system/declaration.py"


def toml_readers(root: Path) -> set[str]:
    """The modules under `root`/iotad that import a TOML parser anywhere in their code."""
    found = set()
    for path in sorted((root / "iotad").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
            if any(name.split(".")[0] in TOML_PARSERS for name in names):
                found.add(path.relative_to(root).as_posix())
    return found


def test_only_the_declaration_imports_a_toml_parser():
    assert toml_readers(ROOT) == {READER}


def test_the_declaration_parses_the_system_file_and_a_sweep_file_alike(tmp_path):
    # a sweep file that is a system file too is read through the declaration's reader
    from iotad.launcher.system.declaration import read_toml
    from iotad.sweep.plan import read_sweep_file

    system = tmp_path / "s.toml"
    system.write_text('[[node]]\nname = "a"\npython = "m:C"\n[sweep]\nmetrics = "m:f"\n')
    assert read_toml(system)["node"][0]["name"] == "a"
    assert read_sweep_file(system) is None  # a system file names no other system: it is one


def test_the_guard_sees_a_second_reader_even_inside_a_function(tmp_path):
    (tmp_path / "iotad" / "launcher" / "system").mkdir(parents=True)
    (tmp_path / "iotad" / "launcher" / "system" / "declaration.py").write_text("import tomllib\n")
    (tmp_path / "iotad" / "launcher" / "hosts").mkdir(parents=True)
    (tmp_path / "iotad" / "launcher" / "hosts" / "code.py").write_text("def f(t):\n    from tomllib import loads\n    return loads(t)\n")
    assert toml_readers(tmp_path) == {READER, "iotad/launcher/hosts/code.py"}
