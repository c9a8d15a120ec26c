"""ESPRIT, the specification language of the paper (Figure 2): parse, check, compile to IOTAs.

    from iotad.esprit import load_iota
    scheduler = load_iota("nodes/scheduler/scheduler.iota", N=3)

`load_file`/`load_text` give a `Module` (IOTA factories, struct types); `load_iota` gives a
ready instance. Every problem with a spec is an `EspritError` naming `file:line:col`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from .static_checks import Checker
from .compiler import Compiler, IotaFactory, Module
from .errors import Diagnostic, EspritError, Source
from .parser import parse
from iotad.kernel.text_file import read_text_file

__all__ = ["Diagnostic", "EspritError", "IotaFactory", "Module", "check_text", "load_file", "load_iota", "load_text"]


def load_text(text: str, filename: str = "<spec>", externs: dict[str, Callable] | None = None) -> Module:
    """Parse, check and compile a spec. `externs` gives Python functions for `extern`
    declarations without a `= "module:function"` target (and overrides those with one)."""
    source = Source(text, filename)
    try:
        checked = _check(source, externs)
        if checked.errors:
            raise EspritError(checked.errors[0], checked.errors)
        return Compiler(checked, source).module()
    except EspritError:
        raise
    except (RecursionError, SyntaxError, MemoryError):  # SyntaxError: Python's limits on nesting
        raise source.error(None, "the spec nests too deeply") from None
    except Exception as exc:  # noqa: BLE001 - a spec must never crash the loader
        raise source.error(None, f"internal compiler error (please report it): {type(exc).__name__}: {exc}") from exc


def check_text(text: str, filename: str = "<spec>", externs: dict[str, Callable] | None = None):
    """Every diagnostic of a spec, errors and warnings, without raising for check errors.
    Returns (errors, warnings); a syntax error is the only error when the text does not parse."""
    source = Source(text, filename)
    try:
        checked = _check(source, externs)
    except EspritError as exc:
        return exc.diagnostics, []
    if checked.errors:
        return checked.errors, checked.warnings
    try:
        Compiler(checked, source).module()
    except EspritError as exc:
        return exc.diagnostics, checked.warnings
    except (RecursionError, SyntaxError, MemoryError):  # SyntaxError: Python's limits on nesting
        return source.error(None, "the spec nests too deeply").diagnostics, checked.warnings
    return [], checked.warnings


def load_file(path: str | Path, externs: dict[str, Callable] | None = None) -> Module:
    path = Path(path)
    try:
        text = read_text_file(path)
    except (OSError, UnicodeDecodeError) as exc:
        raise EspritError(Diagnostic(str(path), 1, 1, f"cannot read the spec: {exc}")) from None
    return load_text(text, str(path), externs)


def load_iota(path_or_text: str | Path, iota: str | None = None, name: str | None = None,
              externs: dict[str, Callable] | None = None, **params: Any) -> Any:
    """A ready instance of `iota` (default: the last IOTA of the file) from a file path or spec
    text: an `iotad.kernel.model.Instance`, or a `Composite` when the IOTA has an inclusion part."""
    if isinstance(path_or_text, Path) or ("\n" not in path_or_text and "{" not in path_or_text):
        module = load_file(path_or_text, externs)
    else:
        module = load_text(path_or_text, "<spec>", externs)
    return module.factory(iota)(name, **params)


def _check(source: Source, externs: dict[str, Callable] | None):
    program = parse(source)
    base = Path(source.filename).resolve().parent if not source.filename.startswith("<") else Path.cwd()
    return Checker(source, _extern_resolver(source, externs or {}, base)).check(program)


def _extern_resolver(source: Source, given: dict[str, Callable], base: Path):
    from iotad.kernel.python_loader import load_object

    def resolve(decl) -> Callable | None:
        if decl.name in given:
            function = given[decl.name]
        elif decl.target is None:
            raise source.error(decl.pos, f"extern {decl.name} names no Python function: write "
                                         f"= \"module:function\" or pass externs={{'{decl.name}': f}}")
        else:
            try:
                function = load_object(decl.target, base)
            except Exception as exc:  # noqa: BLE001 - any failure to import is the spec's error
                raise source.error(decl.pos, f"extern {decl.name}: cannot load {decl.target}: {exc}") from None
        if not callable(function):
            raise source.error(decl.pos, f"extern {decl.name}: {decl.target or 'the given object'} is not callable")
        return function
    return resolve
