"""The client side: hand one command to a running build server, or say there is none.

`forward(argv)` returns the command's exit code when a server ran it, and None when the caller
must run it itself: no server, servers disabled (`BLENDSPACE_NO_SERVER=1`), a platform without
descriptor passing, or a server whose code or `sys.path` differs from the caller's. Without a
server this costs one stat call.

The wire format is one JSON object per line in each direction. The request goes out in one
`sendmsg` with the caller's stdin, stdout and stderr attached, so the command writes to the
caller's terminal or pipe itself; nothing is relayed. Ctrl-C sends one byte, and the server's
process raises KeyboardInterrupt just as a local run would.
"""

from __future__ import annotations

import json
import os
import socket
import sys

from blendspace_pipeline.server.address import (
    disabled,
    fingerprint,
    log_path,
    private_problem,
    socket_path,
    supported,
)

TYPE_CHECKING = False  # `typing` is not imported for this (4 ms of every served command)
if TYPE_CHECKING:
    from typing import Any

INTERRUPT = b"i"
HANDSHAKE_SECONDS = 10.0
EXIT_INTERNAL = 3  # errors.EXIT_INTERNAL, repeated so a client imports nothing of the tool


class _Lines:
    """Newline-separated JSON messages from a stream socket."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.buffer = b""

    def next(self) -> dict[str, Any] | None:
        while b"\n" not in self.buffer:
            chunk = self.sock.recv(65536)
            if not chunk:
                return None
            self.buffer += chunk
        line, self.buffer = self.buffer.split(b"\n", 1)
        message: dict[str, Any] = json.loads(line)
        return message


def connect() -> socket.socket | None:
    """A connection to this installation's server, or None when none listens (or it is not safe)."""
    if not supported():
        return None
    path = socket_path()
    try:
        os.stat(path)
    except OSError:
        return None
    if private_problem(path.parent) is not None:
        return None
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.settimeout(HANDSHAKE_SECONDS)
        sock.connect(str(path))
    except OSError:  # a socket left by a server that died: nobody listens
        sock.close()
        return None
    return sock


def ask(op: str) -> dict[str, Any] | None:
    """One control request (`status`, `stop`); None when no server answers."""
    sock = connect()
    if sock is None:
        return None
    with sock:
        try:
            sock.sendall(json.dumps({"op": op, "fingerprint": fingerprint()}).encode() + b"\n")
            return _Lines(sock).next()
        except (OSError, ValueError):
            return None


def _streams() -> tuple[list[int], list[dict[str, str | None]]]:
    """The caller's standard descriptors that are open, and how Python encodes text on each."""
    fds: list[int] = []
    described: list[dict[str, str | None]] = []
    for fd, stream in ((0, sys.stdin), (1, sys.stdout), (2, sys.stderr)):
        try:
            os.fstat(fd)
        except OSError:
            described.append({"fd": None})
            continue
        fds.append(fd)
        described.append(
            {
                "fd": str(fd),
                "encoding": getattr(stream, "encoding", None),
                "errors": getattr(stream, "errors", None),
            }
        )
    return fds, described


def forward(argv: list[str]) -> int | None:
    """Run ``argv`` in the server; its exit code, or None to run it in this process."""
    if disabled():
        return None
    sock = connect()
    if sock is None:
        return None
    with sock:
        try:
            cwd = os.getcwd()
        except OSError:  # the working folder was deleted: let the local run report it
            return None
        fds, streams = _streams()
        request = {
            "op": "run",
            "argv": argv,
            "cwd": cwd,
            "env": dict(os.environ),
            "umask": _umask(),
            "cpus": _cpus(),
            "nice": os.nice(0) if hasattr(os, "nice") else None,
            "streams": streams,
            "fingerprint": fingerprint(),
        }
        try:
            socket.send_fds(sock, [json.dumps(request).encode() + b"\n"], fds)
            lines = _Lines(sock)
            accepted = lines.next()
        except (OSError, ValueError):
            return None
        if not accepted or not accepted.get("accepted"):
            return None  # another environment, or a server whose code moved: run here
        sock.settimeout(None)  # a build takes as long as it takes
        return _wait(sock, lines)


def _wait(sock: socket.socket, lines: _Lines) -> int:
    interrupted = False
    while True:
        try:
            done = lines.next()
        except KeyboardInterrupt:
            if interrupted:  # a second Ctrl-C: stop waiting; the server's process is told by EOF
                return 130
            interrupted = True
            try:
                sock.sendall(INTERRUPT)
            except OSError:
                return 130
            continue
        except (OSError, ValueError):
            done = None
        if done is None or "exit" not in done:
            sys.stderr.write(
                "blendspace: the build server's process ended without an exit code "
                f"(its log: {log_path()}); set BLENDSPACE_NO_SERVER=1 to run without the server\n"
            )
            return EXIT_INTERNAL
        return int(done["exit"])


def _cpus() -> list[int] | None:
    """The CPUs this process may run on (`taskset`, a cpuset): the served command runs on them,
    and its `--jobs auto` counts them, as it would here."""
    try:
        return sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return None


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask
