"""Loading a Python IOTA class named as "path/to/file.py:Class" or "package.module:Class", or from
the source text a recording stored (`module_from_text`), with the texts of the modules beside it
that it imports (`neighbour_sources`)."""
from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.abc
import importlib.util
import linecache
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any


class LoadError(Exception):
    pass


class _ExitAtLoad(BaseException):
    """os._exit() called by a module as it loads (see `_exits_refused`)."""

    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


@contextmanager
def _exits_refused():
    """While a user's module loads, os._exit() raises instead of ending the process: it would end
    whoever loads it (the CLI checking a system file, a node host) at once, with its status and
    without a word, where nothing can catch it. Loading is single-threaded; the original is put
    back whatever happens."""
    original = os._exit

    def refused(code: int) -> None:
        raise _ExitAtLoad(code)

    os._exit = refused
    try:
        yield
    finally:
        os._exit = original


def load_object(reference: str, base: Path | None = None) -> Any:
    if ":" not in reference:
        raise LoadError(f"{reference!r}: expected 'file.py:Class' or 'module:Class'")
    where, name = reference.rsplit(":", 1)
    if where.endswith(".py"):
        path = Path(where)
        if not path.is_absolute() and base is not None:
            path = base / path
        if not path.is_file():
            raise LoadError(f"{reference!r}: no file {path}")
        # named after its path by a stable digest: str hash() changes from process to process,
        # and the name ends up in recordings (specs name their module), which must not differ
        # between two identical runs
        digest = hashlib.blake2s(str(path.resolve()).encode(), digest_size=8).hexdigest()
        module_name = f"_iotad_user_{path.stem}_{digest}"
        module = sys.modules.get(module_name)
        if module is None:
            # The file's folder goes on sys.path so that it can import its neighbours.
            folder = str(path.resolve().parent)
            if folder not in sys.path:
                sys.path.insert(0, folder)
            spec = importlib.util.spec_from_file_location(module_name, path)
            module = importlib.util.module_from_spec(spec)
            sys.modules[module_name] = module
            try:
                with _exits_refused():
                    spec.loader.exec_module(module)
            except (Exception, SystemExit, _ExitAtLoad) as exc:
                del sys.modules[module_name]
                raise LoadError(f"{path}: {_why(exc)}") from exc
    else:
        try:
            with _exits_refused():
                module = importlib.import_module(where)
        except ImportError as exc:
            raise LoadError(f"{reference!r}: cannot import {where}: {exc}") from exc
        except (SystemExit, _ExitAtLoad) as exc:
            raise LoadError(f"{reference!r}: {_why(exc)}") from exc
    try:
        return getattr(module, name)
    except AttributeError:
        raise LoadError(f"{reference!r}: {where} has no {name}") from None


def _why(exc: BaseException) -> str:
    # A module that calls sys.exit() as it loads would end whoever loads it (the CLI, a node
    # host) silently, with its status: it is a load error like any other.
    if isinstance(exc, SystemExit):
        return f"it called sys.exit({exc.code!r}) as it loaded"
    if isinstance(exc, _ExitAtLoad):
        return f"it called os._exit({exc.code!r}) as it loaded"
    return f"{type(exc).__name__}: {exc}"


def iota_factory(reference: str, base: Path | None = None) -> Any:
    """`load_object`, checked to make IOTAs: an `Iota` or `Composite` subclass, or a function
    (which returns one); a module or another class is a LoadError that says what it is."""
    import inspect

    from iotad.kernel.api import Iota
    from iotad.kernel.compose import Composite

    found = load_object(reference, base)
    if inspect.ismodule(found):
        raise LoadError(f"{reference!r}: {found.__name__} is a module, not an IOTA class")
    if inspect.isclass(found) and not issubclass(found, (Iota, Composite)):
        raise LoadError(f"{reference!r}: {found.__name__} is a class but not an IOTA (a subclass of iotad.Iota)")
    if inspect.isclass(found):
        return found
    # A function is called to build the IOTA, even by `iotad run --check`: only one that says it
    # builds one (`-> SomeIota`), never whatever a reference happens to name (os:system, shutil:rmtree)
    if not inspect.isfunction(found):
        raise LoadError(f"{reference!r}: {type(found).__name__} {_shown(found)} is not an IOTA class")
    if not _builds_an_iota(found):
        raise LoadError(f"{reference!r}: {found.__name__} is a function that does not say it returns an IOTA; "
                        "name an IOTA class, or annotate the factory's return type (-> MyIota)")
    return found


def _builds_an_iota(function: Any) -> bool:
    import typing

    from iotad.kernel.api import Iota
    from iotad.kernel.compose import Composite

    try:
        returned = typing.get_type_hints(function).get("return")
    except Exception:  # noqa: BLE001 - an annotation that does not resolve says nothing
        return False
    return isinstance(returned, type) and issubclass(returned, (Iota, Composite))


def _shown(found: Any) -> str:
    text = repr(found)
    return text if len(text) <= 80 else text[:77] + "..."


def package_of(module: str | None, where: str) -> str | None:
    """The package a stored module's relative imports (`from .joint_map import ...`) resolve
    in: from the recorded module name, or from a `package.module` reference (`where`); None for
    a file that is no package's module."""
    if not module and where and not where.endswith(".py"):
        module = where  # a "package.module:Class" reference
    if not module or module == "__main__":
        return None
    try:
        found = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        found = None
    if found is not None and found.submodule_search_locations is not None:
        return module  # the text is the package's __init__
    return module.rpartition(".")[0] or None


# the most source text a node's neighbours may add to its stored spec (a folder of data files
# named .py is no reason to make every recording megabytes larger)
NEIGHBOURS_LIMIT = 1 << 20


def neighbour_sources(file: str | Path) -> dict[str, str]:
    """The source texts of the modules beside `file` (in its folder, no package's) that it imports,
    and those they import, by module name: what a recording stores with a node's own text, so that
    the node can be rebuilt where that folder is gone or has changed (a check on another machine,
    or after an edit). Modules of packages and installed ones are left to the import system."""
    folder = Path(file).parent
    found: dict[str, str] = {}
    pending = [Path(file)]
    size = 0
    while pending:
        try:
            tree = ast.parse(pending.pop().read_text())
        except (OSError, SyntaxError, ValueError, UnicodeDecodeError):
            continue  # the node's own load says what is wrong with it
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.partition(".")[0]
                path = folder / f"{top}.py"
                if top in found or top == Path(file).stem or not path.is_file():
                    continue
                try:
                    text = path.read_text()
                except (OSError, UnicodeDecodeError):
                    continue
                size += len(text)
                if size > NEIGHBOURS_LIMIT:
                    return found
                found[top] = text
                pending.append(path)
    return found


class _StoredModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports the neighbour modules a recording stored, from their texts, ahead of any file."""

    def __init__(self, texts: dict[str, str]):
        self.texts = texts

    def find_spec(self, name, path=None, target=None):
        if name not in self.texts:
            return None
        return importlib.util.spec_from_loader(name, self, origin=f"<recorded {name}.py>")

    def create_module(self, spec):
        return None

    def exec_module(self, module) -> None:
        text = self.texts[module.__name__]
        filename = f"<recorded {module.__name__}.py {hashlib.sha1(text.encode()).hexdigest()[:12]}>"
        linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
        module.__file__ = filename
        exec(compile(text, filename, "exec"), module.__dict__)


@contextmanager
def _neighbours_from(texts: dict[str, str] | None):
    """While a stored node's module runs: its stored neighbours are what `import` finds by their
    names, not the files of the same names (changed since, or gone) nor modules of those names
    this process imported before; afterwards, whatever was there before is back."""
    if not texts:
        yield
        return
    saved = {name: sys.modules.pop(name) for name in texts if name in sys.modules}
    finder = _StoredModules(texts)
    sys.meta_path.insert(0, finder)
    try:
        yield
    finally:
        sys.meta_path.remove(finder)
        for name in texts:
            sys.modules.pop(name, None)
        sys.modules.update(saved)


def module_from_text(text: str, file: str, package: str | None = None,
                     neighbours: dict[str, str] | None = None) -> Any:
    """Import a Python source stored in a recording as a module (a LoadError if it does not run);
    its text goes to linecache so that the
    dependency analysis (iotad.kernel.dependencies) can still read the functions' source.
    In `package` (imported first), so that its relative imports find the package's modules.
    `neighbours`: the stored texts of the modules beside it that it imports (`neighbour_sources`),
    which it gets instead of the files; without them (an older recording), the files, where they
    still are."""
    neighbours = {str(k): v for k, v in (neighbours or {}).items() if isinstance(v, str)}
    digest = hashlib.sha1("\0".join([text, *(f"{k}\0{v}" for k, v in sorted(neighbours.items()))]).encode()
                          ).hexdigest()[:12]
    name = f"_iotad_recorded_{digest}"
    if package:
        try:
            importlib.import_module(package)
            name = f"{package}.{name}"
        except ImportError:
            pass  # not installed here: relative imports will say so
    module = sys.modules.get(name)
    if module is not None:
        return module
    filename = f"<recorded {Path(file).name or 'spec'} {digest}>"
    linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
    folder = str(Path(file).parent) if file else ""
    if folder and Path(folder).is_dir() and folder not in sys.path:
        sys.path.append(folder)  # neighbours it imports, if they are still there
    spec = importlib.util.spec_from_loader(name, loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__file__ = filename
    sys.modules[name] = module
    try:
        with _neighbours_from(neighbours):
            exec(compile(text, filename, "exec"), module.__dict__)
    except Exception as exc:
        del sys.modules[name]
        raise LoadError(f"stored source of {file}: {type(exc).__name__}: {exc}") from None
    return module
