"""Code by content hash: the files a system file names (node code and specs) travel from the hub's
machine to an agent by their sha256, so that an agent runs exactly the hub's version of each.

The hub lists every file its system file names, with its sha256 (`named_files`), and answers
`iota/@code/<sha256>` with that file's bytes; it serves those files and no other. An agent keeps
each file it has at the hub's path with the same hash; any other (missing here, or another
version) it fetches by hash, checks that the bytes hash to what was asked (refusing the run
otherwise), and stores in its cache, `<workdir>/code/<sha256>/<file name>`: a file is fetched
once, and two versions of one file never overwrite each other. The agent's run then reads the
hub's system file with each name it writes standing for this machine's copy (`localize`).

Only the named files travel, not the repository: a node file's own imports (its neighbours, the
`channels` package, iotad itself) come from the agent's checkout."""
from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Callable

from iotad.launcher.system.declaration import Declaration

def sha256_of(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class CodeError(Exception):
    """A named file that cannot be had at the version the hub runs: one line for the user."""


def named_files(declaration: Declaration) -> list[dict]:
    """Every file the system's nodes name (`spec = "file.iota"`, `python = "file.py:Class"`), as
    {"written": as the file writes it, "path": the absolute path on this machine, "sha256"}, from
    the declaration (which found each file where the system file's folder says). Files that do not
    exist are left out: checking the system file says so, before any order."""
    files, seen = [], set()
    for node in declaration.nodes.values():
        written = node.file
        if written is None or written in seen:
            continue
        path = Path(node.source["file"] if node.source["kind"] == "esprit" else node.source["ref"].rsplit(":", 1)[0])
        if path.is_file():
            seen.add(written)
            files.append({"written": written, "path": str(path), "sha256": sha256_of(path.read_bytes())})
    return files


class CodeCache:
    """An agent's files by hash, under `<workdir>/code`."""

    def __init__(self, workdir: Path):
        self.folder = Path(workdir) / "code"

    def path_for(self, sha256: str, name: str) -> Path:
        return self.folder / sha256 / name

    def holds(self, sha256: str, name: str) -> bool:
        path = self.path_for(sha256, name)
        try:
            return path.is_file() and sha256_of(path.read_bytes()) == sha256
        except OSError:
            return False

    def store(self, sha256: str, name: str, data: bytes) -> Path:
        """Write `data` as the file `sha256` names, refusing bytes that hash to anything else."""
        got = sha256_of(data)
        if got != sha256:
            raise CodeError(f"{name}: the hub sent bytes whose sha256 is {got[:12]}, not the {sha256[:12]} "
                            "the run names: refused (damaged in transit, or not the hub's file)")
        path = self.path_for(sha256, name)
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(path.name + ".part")  # never a half-written file under its final name
        partial.write_bytes(data)
        partial.replace(path)
        return path


def localize(files: list, cache: CodeCache, fetch: Callable[[str], bytes]) -> tuple[dict[str, str], list[str]]:
    """Where this machine has the hub's version of each file an order names: ({name as the
    system file writes it: the file here}, the lines saying which files were fetched). A file at
    the hub's path with the same hash is that one; any other is fetched by hash into the cache.
    `fetch(sha256)` asks the hub for a file's bytes. The declaration of the order's system file
    then names these (`parse_declaration(..., files=...)`): no copy of the file is written."""
    if not isinstance(files, list):
        raise CodeError("an order's 'files' must be a list")
    replaced: dict[str, str] = {}
    said = []
    for item in files:
        if not isinstance(item, dict) or not all(isinstance(item.get(k), str) for k in ("written", "path", "sha256")) \
                or not re.fullmatch(r"[0-9a-f]{64}", item["sha256"]):
            raise CodeError(f"an order names a file without its written name, path and sha256: {item!r}")
        written, hub_path, sha = item["written"], Path(item["path"]), item["sha256"]
        if _hash_of(hub_path) == sha:
            replaced[written] = str(hub_path)  # this checkout holds the hub's version at its path
            continue
        name = hub_path.name
        if not name.endswith((".py", ".iota")) or name.startswith("."):
            # a node names a .py or .iota file; anything else is no order of a hub (and must not
            # name a place outside the cache)
            raise CodeError(f"an order names {written!r} at {hub_path}: not a node's .py or .iota file")
        if not cache.holds(sha, name):
            why = "another version is" if hub_path.is_file() else "no file is"
            cache.store(sha, name, fetch(sha))
            said.append(f"{written}: {why} at {hub_path} here; fetched sha256 {sha[:12]} from the hub")
        replaced[written] = str(cache.path_for(sha, name))
    return replaced, said


def _hash_of(path: Path) -> str | None:
    try:
        return sha256_of(path.read_bytes()) if path.is_file() else None
    except OSError:
        return None
