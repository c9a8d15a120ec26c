"""Credentials for zenoh's user-password authentication: the private files that `iotad run`
makes for one run, and how a process finds its own (docs/access-control.md).

`iotad run` makes a fresh directory (mode 0700, files 0600) under the system's temporary
directory, never in the repository or a recording: one `USER.json` per user (`{"user",
"password"}`, random passwords of 192 bits) and the hub's `dictionary.txt` (`user:password`
lines, what zenoh's `transport/auth/usrpwd/dictionary_file` reads). A child of the launcher
learns its file from the environment variable `IOTAD_CREDENTIALS`; a command-line tool started by
hand finds the tools' file through a pointer `hub-PORT-netN` in the per-user directory
`$TMPDIR/iotad-UID` (0700), which `iotad run` writes once its hub listens on PORT; N names the
network namespace the hub listens in. A port number alone names no hub: a run under access control
in another namespace (another test "host", a container) on the same port is another hub, and a
tool or recorder that showed its password to an open hub here would be refused, for ever.
"""
from __future__ import annotations

import json
import os
import re
import secrets
import shutil
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

ENV = "IOTAD_CREDENTIALS"
HUB_USER = "iotad-hub"


class CredentialsError(ValueError):
    """Credentials that cannot be used; `str()` is one line for the user."""


@dataclass(frozen=True)
class Credentials:
    user: str
    password: str
    dictionary: str | None = None  # the hub's: the `user:password` file it checks others against
    # the keys this user may publish on, where the run wrote them down (the tools' file): a tool
    # can then say at once that the hub would drop a message, which zenoh never tells the sender
    may_publish: tuple[str, ...] | None = None

    def zenoh_usrpwd(self) -> dict:
        """The value of zenoh's `transport/auth/usrpwd`."""
        value = {"user": self.user, "password": self.password}
        if self.dictionary:
            value["dictionary_file"] = self.dictionary
        return value


def load(path: str | Path) -> Credentials:
    try:
        data = json.loads(Path(path).read_text())
    except OSError as exc:
        raise CredentialsError(f"cannot read credentials {path}: {exc.strerror or exc}") from None
    except json.JSONDecodeError:
        raise CredentialsError(f"credentials {path}: not JSON") from None
    if not isinstance(data, dict) or not all(isinstance(data.get(k), str) and data.get(k) for k in ("user", "password")):
        raise CredentialsError(f"credentials {path}: expected {{\"user\": ..., \"password\": ...}}")
    allowed = data.get("may_publish")
    if not (isinstance(allowed, list) and all(isinstance(k, str) for k in allowed)):
        allowed = None
    return Credentials(data["user"], data["password"], may_publish=None if allowed is None else tuple(allowed))


def from_env() -> Credentials | None:
    """The credentials the launcher gave this process (`IOTAD_CREDENTIALS`), or None."""
    path = os.environ.get(ENV)
    return load(path) if path else None


def user_dir() -> Path:
    """Where pointers to running systems' tool credentials live: private to this user."""
    return Path(tempfile.gettempdir()) / f"iotad-{os.getuid()}"


def _private_dir(path: Path) -> bool:
    try:
        info = path.lstat()
    except OSError:
        return False
    return stat.S_ISDIR(info.st_mode) and info.st_uid == os.getuid() and not info.st_mode & 0o077


def _port(endpoint: str) -> str | None:
    match = re.search(r":(\d+)$", endpoint.strip())
    return match.group(1) if match else None


def network_namespace() -> str:
    """This process's network namespace, as the kernel numbers it ("" where it cannot be read):
    two hubs on one port in two namespaces are two hubs."""
    try:
        return str(os.stat("/proc/self/ns/net").st_ino)
    except OSError:
        return ""


def pointer_path(folder: Path, port: int) -> Path:
    """The pointer to the tools' credentials of a hub on `port` in this network namespace."""
    namespace = network_namespace()
    return folder / (f"hub-{port}-net{namespace}" if namespace else f"hub-{port}")


def for_endpoints(endpoints: Iterable[str]) -> Credentials | None:
    """A tool's credentials for a hub at `endpoints`: `IOTAD_CREDENTIALS` when set (set but empty:
    none, as the launcher of an open run tells its processes), else the ones a running `iotad run`
    advertised for that port in this network namespace (only from a private directory of this
    user; the pointer of a run whose launcher is gone, killed before it could remove it, is
    ignored; one named by its port alone, as runs wrote them before, only where it says nothing of
    another namespace)."""
    if ENV in os.environ:
        return from_env()
    folder = user_dir()
    if not _private_dir(folder):
        return None
    for endpoint in endpoints:
        port = _port(endpoint)
        if port is None:
            continue
        pointer = pointer_path(folder, port)
        if not pointer.is_file():
            pointer = folder / f"hub-{port}"  # written by an older run, or where /proc is not
            if not pointer.is_file():
                continue
        try:
            target, owner, namespace = _read_pointer(pointer)
        except OSError:
            continue
        if namespace is not None and namespace != network_namespace():
            continue  # a hub on this port in another network namespace: another hub
        if owner is not None and not _alive(owner):
            continue  # a run killed before it took its pointer back: its hub is gone or another's
        if _private_dir(target.parent) and target.is_file():
            try:
                return load(target)
            except CredentialsError:
                continue
    return None


def _read_pointer(pointer: Path) -> tuple[Path, int | None, str | None]:
    """A pointer's credentials file, the pid of the launcher that wrote it and the network
    namespace of its hub (None in a pointer written before they were kept)."""
    lines = pointer.read_text().splitlines()
    owner = lines[1].strip() if len(lines) > 1 else ""
    namespace = lines[2].strip() if len(lines) > 2 and lines[2].strip() else None
    return Path(lines[0].strip() if lines else ""), int(owner) if owner.isdigit() else None, namespace


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process: alive, and not this user's run (the folder check says so)
    return True


class CredentialStore:
    """One run's credentials: a private directory with one file per user and the hub's
    dictionary. `remove()` deletes it all (and the pointer), which the launcher does at its end."""

    def __init__(self, users: Iterable[str], parent: str | None = None,
                 may_publish: dict[str, list[str]] | None = None, passwords: dict[str, str] | None = None):
        """`may_publish`: for some users, the keys they may publish on, written into their file.
        `passwords`: the passwords of some users, fixed elsewhere (a host's agent secret, or the
        credentials an agent received from the hub); the others get fresh random ones."""
        self.folder = Path(tempfile.mkdtemp(prefix="iotad-credentials-", dir=parent))
        os.chmod(self.folder, 0o700)
        self._passwords = {user: secrets.token_urlsafe(24) for user in [HUB_USER, *users]}
        self._passwords.update(passwords or {})
        for user, password in self._passwords.items():
            if ":" in user or "\n" in user:
                raise CredentialsError(f"user name {user!r} cannot hold ':' or a line break")
            entry = {"user": user, "password": password}
            if may_publish is not None and user in may_publish:
                entry["may_publish"] = list(may_publish[user])
            self._write(self.file_of(user), json.dumps(entry))
        self.dictionary = self.folder / "dictionary.txt"
        self._write(self.dictionary, "".join(f"{u}:{p}\n" for u, p in self._passwords.items()))
        self.pointer: Path | None = None

    @staticmethod
    def _write(path: Path, text: str) -> None:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w") as stream:
            stream.write(text)

    def file_of(self, user: str) -> Path:
        return self.folder / (re.sub(r"[^\w.-]", "_", user) + ".json")

    def credentials(self, user: str) -> Credentials:
        return Credentials(user, self._passwords[user])

    def hub(self) -> Credentials:
        return Credentials(HUB_USER, self._passwords[HUB_USER], str(self.dictionary))

    def advertise(self, endpoints: Iterable[str], user: str) -> None:
        """Let tools started by hand find `user`'s file for the hub at `endpoints`."""
        folder = user_dir()
        folder.mkdir(mode=0o700, exist_ok=True)
        if not _private_dir(folder):
            return  # someone else's or an open directory: tools then need IOTAD_CREDENTIALS
        for endpoint in endpoints:
            port = _port(endpoint)
            if port is None:
                continue
            pointer = pointer_path(folder, port)
            temporary = folder / f".hub-{port}.{os.getpid()}"
            temporary.unlink(missing_ok=True)
            self._write(temporary, f"{self.file_of(user)}\n{os.getpid()}\n{network_namespace()}\n")
            os.replace(temporary, pointer)
            self.pointer = pointer
            return

    def remove(self) -> None:
        if self.pointer is not None:
            try:
                if str(_read_pointer(self.pointer)[0]).startswith(str(self.folder)):
                    self.pointer.unlink()
            except OSError:
                pass
            self.pointer = None
        shutil.rmtree(self.folder, ignore_errors=True)


class GivenCredentials(CredentialStore):
    """Credentials that another process wrote for this one and owns (a host's agent, for the
    launcher it starts and that launcher's nodes): read here, never removed here."""

    def __init__(self, folder: str | Path):  # noqa: super().__init__ would make new ones
        self.folder, self.pointer, self._passwords = Path(folder), None, {}

    def credentials(self, user: str) -> Credentials:
        return load(self.file_of(user))

    def remove(self) -> None:
        pass


__all__ = ["ENV", "Credentials", "CredentialsError", "CredentialStore", "GivenCredentials", "for_endpoints",
           "from_env", "load"]
