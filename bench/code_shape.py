"""Prints the shape of iotad's code: modules per package, the longest functions, the largest
classes, the largest modules and every import cycle between modules (imports inside functions
included), so that a restructuring can be measured before and after.

    python bench/code_shape.py [ROOT]      ROOT: a checkout (default: this one)
"""
from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from pathlib import Path


def module_name(root: Path, path: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(root: Path, path: Path, known: set[str]) -> set[str]:
    """The modules of `known` that `path` imports, at any depth (inside functions too)."""
    package = module_name(root, path) if path.name == "__init__.py" else module_name(root, path).rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([base] if base else []))
            # `from P import m` imports the module P.m where m is one, else P itself (not both:
            # loading P.m runs P's __init__ first, which is no import P.m chose to make)
            names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base for alias in node.names]
        for name in names:
            if name in known:
                found.add(name)
    found.discard(module_name(root, path))
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", nargs="?", default=str(Path(__file__).resolve().parents[1]),
                        help="a checkout of iotad (default: this one)")
    root = Path(parser.parse_args(argv).root).resolve()
    paths = sorted((root / "iotad").rglob("*.py"))
    known = {module_name(root, p) for p in paths}
    per_package: dict[str, int] = defaultdict(int)
    functions, classes, modules = [], [], []
    graph = {}
    for path in paths:
        name = module_name(root, path)
        if path.name != "__init__.py":
            per_package[name.rpartition(".")[0]] += 1
        tree = ast.parse(path.read_text(encoding="utf-8"))
        modules.append((len(path.read_text(encoding="utf-8").splitlines()), name))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions.append((node.end_lineno - node.lineno + 1, f"{name}:{node.name}"))
            elif isinstance(node, ast.ClassDef):
                methods = sum(isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) for n in node.body)
                classes.append((node.end_lineno - node.lineno + 1, f"{name}:{node.name} ({methods} methods)"))
        graph[name] = imports(root, path, known)
    print(f"code shape of {root}/iotad: {len(paths)} files")
    print("modules per package:")
    for package in sorted(per_package):
        print(f"  {package:32} {per_package[package]}")
    for title, rows in (("longest functions", functions), ("largest classes", classes), ("largest modules", modules)):
        print(f"{title} (lines):")
        for lines, what in sorted(rows, reverse=True)[:5]:
            print(f"  {lines:5}  {what}")
    found = cycles(graph)
    print(f"import cycles between modules (imports inside functions included): {len(found)}")
    for component in found:
        print("  " + " <-> ".join(component))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
