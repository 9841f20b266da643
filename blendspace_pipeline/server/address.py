"""Where a user's build server listens, and a fingerprint of the code it would run.

Standard library only and no work beyond stat calls: every `blendspace` command asks this
before it imports anything heavy.

One server per user and per installation (Python executable + package folder), so two virtual
environments never answer for each other. The socket lives in a private folder (0700, owned by
the user, not a symlink): whoever can connect can run commands as the user.

The fingerprint changes when any installed source file of the tool changes (an editable checkout
being edited, an upgrade) or when a folder on `sys.path` changes (a package installed or removed:
numpy, a studio's rule plugin), so a server never runs code older than what the caller would.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import socket
import stat
import sys
from collections.abc import Callable
from pathlib import Path

SERVER_DIR_VARIABLE = "BLENDSPACE_SERVER_DIR"
NO_SERVER_VARIABLE = "BLENDSPACE_NO_SERVER"

PACKAGE = Path(__file__).resolve().parents[1]


def supported() -> bool:
    """The server forks per command (without exec) and passes the caller's descriptors: Linux.
    macOS has both calls, but forking a process that has loaded system frameworks (Accelerate
    under numpy, the Objective-C runtime) without exec is unsafe there: Python's own
    multiprocessing stopped doing it on macOS in 3.8."""
    return sys.platform.startswith("linux") and hasattr(os, "fork") and hasattr(socket, "send_fds")


def disabled() -> bool:
    return os.environ.get(NO_SERVER_VARIABLE, "") not in ("", "0")


def server_dir() -> Path:
    explicit = os.environ.get(SERVER_DIR_VARIABLE)
    if explicit:
        return Path(explicit)
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime:
        return Path(runtime) / "blendspace"
    return Path(os.environ.get("TMPDIR") or "/tmp") / f"blendspace-{os.getuid()}"


def install_key() -> str:
    identity = f"{sys.executable}\0{PACKAGE}".encode()
    return hashlib.sha256(identity).hexdigest()[:16]


def socket_path() -> Path:
    return server_dir() / f"{install_key()}.sock"


def log_path() -> Path:
    return server_dir() / f"{install_key()}.log"


def private_problem(folder: Path) -> str | None:
    """Why ``folder`` may not hold a server socket, or None when it is private to this user."""
    try:
        info = os.lstat(folder)
    except FileNotFoundError:
        return f"{folder} does not exist"
    except OSError as error:
        return f"cannot read {folder}: {error.strerror or error}"
    if not stat.S_ISDIR(info.st_mode):
        return f"{folder} is not a plain folder"
    if info.st_uid != os.getuid():
        return f"{folder} belongs to another user"
    if info.st_mode & 0o077:
        return f"{folder} can be opened by other users (mode {stat.S_IMODE(info.st_mode):o}; it must be 700)"
    return None


def _code_roots() -> list[Path]:
    """The package, and the built-in rules wherever they are installed (an editable checkout
    keeps them beside the package, in `rules/`)."""
    spec = importlib.util.find_spec("blendspace_pipeline.rules")
    rules = [Path(folder) for folder in (spec.submodule_search_locations or [])] if spec else []
    return [PACKAGE, *(folder for folder in rules if PACKAGE not in folder.parents)]  # no folder twice


def _walk(root: Path, digest: hashlib._Hash) -> None:
    try:
        entries = sorted(os.scandir(root), key=lambda entry: entry.name)
    except OSError:
        return
    for entry in entries:
        if entry.is_dir(follow_symlinks=False):
            if entry.name != "__pycache__":
                _walk(Path(entry.path), digest)
        elif entry.name.endswith((".py", ".json", ".yaml", ".html", ".js", ".css", ".so", ".pyd")):
            info = entry.stat()
            digest.update(f"{entry.path}\0{info.st_mtime_ns}\0{info.st_size}\n".encode())


def fingerprint() -> str:
    """Identity of the code a command would run here: installed sources, interpreter, sys.path."""
    return _fingerprint(_modified)


def installed_fingerprint() -> str:
    """Identity of the code a build runs, for its stamp (`pipeline.stamp`): the tool's sources, the
    interpreter, and per `sys.path` folder the distributions installed there (their
    `*.dist-info`/`*.egg-info` names carry the versions). Unlike `fingerprint` it leaves out the
    folders' modification times: a project folder on `PYTHONPATH` (for `plugins:` by module name)
    that is also the build's output folder changes at every build, and a build would never replay."""
    return _fingerprint(_distributions)


def _fingerprint(state_of: Callable[[str], str]) -> str:
    """The interpreter, each imported `sys.path` folder with ``state_of`` it, and the tool's sources."""
    digest = hashlib.sha256(f"{sys.executable}\0{sys.version}\0".encode())
    for entry in _imported_path():
        digest.update(f"{entry}\0{state_of(entry)}\n".encode())
    for root in _code_roots():
        _walk(root, digest)
    return digest.hexdigest()


def _modified(entry: str) -> str:
    try:
        return str(os.stat(entry or ".").st_mtime_ns)
    except OSError:
        return "0"


def _distributions(entry: str) -> str:
    try:
        return "\0".join(
            sorted(e.name for e in os.scandir(entry or ".") if e.name.endswith((".dist-info", ".egg-info")))
        )
    except OSError:
        return ""


def _imported_path() -> list[str]:
    # sys.path[0] is where the script lies (the venv's bin for `blendspace`, the working folder for
    # `python -m`): it differs between a client and the server without changing what is imported.
    return sys.path if sys.flags.safe_path else sys.path[1:]
