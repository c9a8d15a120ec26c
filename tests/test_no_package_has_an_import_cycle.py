"""No import cycle in iotad: neither between two modules nor between two packages side by side
in one package (iotad.launcher.system and iotad.launcher.hosts, say), counting every import, those
inside functions included. A cycle hidden by a local import is still a cycle: two modules that
need each other are one job in two files, or a job in the wrong one."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def module_name(root: Path, path: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(root: Path) -> dict[str, set[str]]:
    """Module -> the modules of iotad it imports, at any depth. `from P import m` is the module
    P.m where m is one, else P itself (loading P.m runs P's __init__ first, which is no import
    P.m chose to make)."""
    paths = sorted((root / "iotad").rglob("*.py"))
    known = {module_name(root, p) for p in paths}
    graph = {}
    for path in paths:
        name = module_name(root, path)
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                found.update(a.name for a in node.names if a.name in known)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parent = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join(parent + ([base] if base else []))
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    found.add(full if full in known else base)
        graph[name] = {m for m in found if m in known and m != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Every strongly connected component of more than one node, sorted (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, ()))))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter[0]
                    counter[0] += 1
                    stack.append(child)
                    on.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on:
                    low[v] = min(low[v], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
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
    return sorted(out)


def package_graphs(graph: dict[str, set[str]]) -> dict[str, dict[str, set[str]]]:
    """For each package, its members (modules and subpackages) -> the members they import,
    through any module inside them. An import of the package itself, or by its own __init__, is
    no edge between members."""
    out: dict[str, dict[str, set[str]]] = {}
    for source, targets in graph.items():
        for target in targets:
            a, b = source.split("."), target.split(".")
            common = 0
            while common < min(len(a), len(b)) and a[common] == b[common]:
                common += 1
            if common == len(a) or common == len(b):
                continue  # one is the other's package
            parent = ".".join(a[:common])
            out.setdefault(parent, {}).setdefault(a[common], set()).add(b[common])
    return out


def test_no_two_modules_import_each_other_through_any_path():
    assert cycles(import_graph(ROOT)) == []


def test_no_two_packages_side_by_side_import_each_other():
    found = {package: found for package, members in package_graphs(import_graph(ROOT)).items()
             if (found := cycles(members))}
    assert found == {}


def test_the_guard_sees_a_cycle_hidden_in_a_function(tmp_path):
    launcher = tmp_path / "iotad" / "launcher"
    (launcher / "a").mkdir(parents=True)
    (launcher / "b").mkdir(parents=True)
    (launcher / "a" / "one.py").write_text("from iotad.launcher.b import two\n")
    (launcher / "b" / "two.py").write_text("def f():\n    from iotad.launcher.a.three import x\n")
    (launcher / "a" / "three.py").write_text("x = 1\n")
    # no module needs itself back, but package a needs b (one -> two) and b needs a (two -> three)
    assert cycles(import_graph(tmp_path)) == []
    assert cycles(package_graphs(import_graph(tmp_path))["iotad.launcher"]) == [["a", "b"]]
    # three needing one, inside a function and by a relative import, closes a cycle of modules
    (launcher / "a" / "three.py").write_text("def g():\n    from . import one\n")
    assert cycles(import_graph(tmp_path)) == [["iotad.launcher.a.one", "iotad.launcher.a.three", "iotad.launcher.b.two"]]
