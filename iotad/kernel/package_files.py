"""A file named by its Python package, `"nodes.scheduler:program_scheduler.iota"`: the file
`program_scheduler.iota` in the folder of the importable package `nodes.scheduler`, so that a
system file names a shipped spec the same way from any folder."""
from __future__ import annotations

import importlib.util
import re
from pathlib import Path

_PACKAGE = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")


def is_package_ref(written: str) -> bool:
    """Whether `written` is `package.name:file` rather than a path."""
    package, colon, name = written.partition(":")
    return bool(colon) and bool(_PACKAGE.match(package)) and bool(name) and "/" not in package


def package_file(written: str) -> Path:
    """The file `written` (`package.name:relative/file`) names; ValueError saying why not."""
    package, _, name = written.partition(":")
    try:
        found = importlib.util.find_spec(package)
    except (ImportError, ValueError) as exc:
        raise ValueError(f"package {package!r} cannot be imported ({type(exc).__name__}: {exc})") from None
    if found is None or not found.submodule_search_locations:
        what = "no importable package" if found is None else "a module, not a package"
        raise ValueError(f"{package!r} is {what} (a package name such as \"nodes.scheduler\" goes before ':')")
    for folder in found.submodule_search_locations:
        file = (Path(folder) / name).resolve()
        if file.is_file():
            return file
    raise ValueError(f"package {package!r} has no file {name!r} (looked in "
                     f"{', '.join(str(f) for f in found.submodule_search_locations)})")


FILE_SUFFIXES = (".urdf",)  # parameters naming such a file name it as the system file does


def absolute_files(params, base: Path):
    """`params` with every string that names a robot description (`.urdf`) made an absolute path:
    a relative one is relative to the system file's folder `base`, and `package:file` is the file
    in that package's folder, so the node finds its robot whatever folder it runs in. Other
    values, and names of files that do not exist, are left as written (the node says what is wrong)."""
    if isinstance(params, dict):
        return {key: absolute_files(value, base) for key, value in params.items()}
    if isinstance(params, list):
        return [absolute_files(value, base) for value in params]
    if isinstance(params, str) and params.endswith(FILE_SUFFIXES):
        if is_package_ref(params):
            try:
                return str(package_file(params))
            except ValueError:
                return params
        file = (base / params).resolve()
        if file.is_file():
            return str(file)
    return params
