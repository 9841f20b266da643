"""The build server loop: import the tool once, then fork one process per command.

    python -m blendspace_pipeline.server.daemon [--idle-timeout SECONDS]

(`blendspace server start` runs this in the background; `--foreground` there runs it in place.)

Why fork per command and not run commands in the loop: each command gets a fresh copy of an
already-imported interpreter (numpy, scipy, pydantic, usd-core and the tool: about 1.5 s of
imports on a 2-core machine) and nothing a command does (its working folder, environment,
`functools.cache` entries, a plugin it loaded, a crash) can reach the next one. The server itself
never runs a command, so it stays as it was after its imports.

The server stops when its socket has been idle for `--idle-timeout` seconds, on `blendspace server
stop` and on SIGTERM. When its own code changed on disk (an upgrade, an edited checkout, a package
installed on `sys.path`), it answers the command that noticed with "run it yourself" and starts
again in place (exec), so it never runs code older than what is installed.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import io
import json
import os
import pkgutil
import signal
import socket
import struct
import sys
import threading
import time
from typing import Any

from blendspace_pipeline.cpus import own_process, thread_settings
from blendspace_pipeline.server.address import fingerprint, private_problem, server_dir, socket_path
from blendspace_pipeline.server.client import INTERRUPT

DEFAULT_IDLE_TIMEOUT = 3 * 3600.0
# What a build or check imports besides the tool's own modules (the expensive part of a start).
THIRD_PARTY = (
    "numpy",
    "scipy.spatial",
    "scipy.ndimage",
    "pydantic",
    "yaml",
    "pyarrow",
    "pyarrow.csv",
    "pxr.Usd",
    "pxr.UsdSkel",
    "pxr.UsdGeom",
    "pxr.Sdf",
    "pxr.Gf",
    "pxr.Vt",
    "OpenImageIO",
)
# Not preloaded: the server itself, and `__main__` (importing it runs the command line). Dask, for
# `index`, loads inside the function that needs it.
SKIP_PREFIXES = ("blendspace_pipeline.server", "blendspace_pipeline.__main__")


def preload() -> tuple[list[str], dict[str, str]]:
    """Import everything a command may need. Returns the names that could not be imported (optional
    extras) and the environment variables the imports set (OpenImageIO sets `OpenImageIO_ROOT`, where
    its fonts are): a command gets them too, as its own imports would have set them."""
    before = dict(os.environ)
    missing = []
    for name in THIRD_PARTY:
        try:
            importlib.import_module(name)
        except ImportError:
            missing.append(name)
    for package in (
        importlib.import_module(name) for name in ("blendspace_pipeline", "blendspace_pipeline.rules")
    ):
        for module in pkgutil.walk_packages(package.__path__, f"{package.__name__}."):
            if module.name.startswith(SKIP_PREFIXES):
                continue
            try:
                importlib.import_module(module.name)
            except ImportError:
                missing.append(module.name)
    return missing, {k: v for k, v in os.environ.items() if before.get(k) != v}


class Server:
    def __init__(self, idle_timeout: float, imported_env: dict[str, str]) -> None:
        self.idle_timeout = idle_timeout
        self.imported_env = imported_env
        self.fingerprint = fingerprint()
        self.threads = thread_settings(os.environ)  # fixed in this process since usd-core and numpy loaded
        self.started = time.time()
        self.served = 0
        self.stale = False  # set when the installed code moved: the server starts again, fresh
        self.last_command = time.monotonic()  # idle time counts from here (status requests do not count)
        self.path = socket_path()
        self.listener: socket.socket | None = None
        self.inode = 0

    def bind(self) -> None:
        """Listen on the socket path, atomically: a client never finds a socket nobody answers yet."""
        folder = self.path.parent
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        problem = private_problem(folder)
        if problem is not None:
            raise SystemExit(f"blendspace server: {problem}")
        staging = folder / f".{self.path.stem}.{os.getpid()}"
        staging.unlink(missing_ok=True)
        listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        listener.bind(str(staging))
        listener.listen(64)
        os.replace(staging, self.path)
        self.inode = os.stat(self.path).st_ino
        self.listener = listener

    def release(self) -> None:
        """Remove the socket, unless a newer server has already put its own in its place."""
        try:
            if os.stat(self.path).st_ino == self.inode:
                self.path.unlink()
        except OSError:
            pass
        if self.listener is not None:
            self.listener.close()

    def loop(self) -> None:
        assert self.listener is not None
        while True:
            left = self.idle_timeout - (time.monotonic() - self.last_command)
            if left <= 0:
                return
            self.listener.settimeout(min(left, 60.0))
            try:
                conn, _ = self.listener.accept()
            except TimeoutError:
                continue
            try:
                if not self.handle(conn):
                    return
            except Exception as error:  # a broken client must not take the server down
                sys.stderr.write(f"blendspace server: request failed: {type(error).__name__}: {error}\n")
            finally:
                conn.close()

    def handle(self, conn: socket.socket) -> bool:
        """Answer one connection; False when the server must stop."""
        conn.settimeout(10.0)
        if not _same_user(conn):
            return True
        request, fds = _receive(conn)
        try:
            op = request.get("op")
            if op == "status":
                _reply(conn, self.status(request))
                return True
            if op == "stop":
                _reply(conn, {"stopping": True})
                return False
            if op != "run":
                _reply(conn, {"error": f"unknown request {op!r}"})
                return True
            if fingerprint() != self.fingerprint:
                _reply(conn, {"accepted": False, "why": "the tool changed on disk since the server started"})
                self.stale = True
                return False
            if request.get("fingerprint") != self.fingerprint:
                _reply(conn, {"accepted": False, "why": "the caller's interpreter or sys.path differs"})
                return True
            if thread_settings(request.get("env") or {}) != self.threads:
                why = "the caller's thread settings (PXR_WORK_THREAD_LIMIT, OPENBLAS_NUM_THREADS, ...) differ"
                _reply(conn, {"accepted": False, "why": why})
                return True
            try:
                pid = os.fork()
            except OSError as error:  # out of memory or processes: the caller runs it itself
                _reply(conn, {"accepted": False, "why": f"cannot fork: {error.strerror or error}"})
                return True
            if pid == 0:  # the command's process (it says "accepted", then the exit code): never returns
                _run_command(conn, self.listener, request, fds, self.imported_env)
            self.served += 1
            self.last_command = time.monotonic()
            return True
        finally:
            for fd in fds:
                os.close(fd)

    def status(self, request: dict[str, Any]) -> dict[str, Any]:
        return {
            "pid": os.getpid(),
            "started": self.started,
            "served": self.served,
            "idle_timeout": self.idle_timeout,
            "python": sys.executable,
            "socket": str(self.path),
            "matches": request.get("fingerprint") == self.fingerprint,
            "current": fingerprint() == self.fingerprint,
        }


def _same_user(conn: socket.socket) -> bool:
    """The socket's folder is private already; where the kernel tells the peer's uid, check it too."""
    if not hasattr(socket, "SO_PEERCRED"):
        return True
    credentials = conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
    _pid, uid, _gid = struct.unpack("3i", credentials)
    return bool(uid == os.getuid())


def _receive(conn: socket.socket) -> tuple[dict[str, Any], list[int]]:
    data, fds, _flags, _address = socket.recv_fds(conn, 1 << 20, 3)
    while not data.endswith(b"\n"):
        more = conn.recv(1 << 20)
        if not more:
            break
        data += more
    request: dict[str, Any] = json.loads(data)
    return request, list(fds)


def _reply(conn: socket.socket, message: dict[str, Any]) -> None:
    conn.sendall(json.dumps(message).encode() + b"\n")


def _run_command(
    conn: socket.socket,
    listener: socket.socket | None,
    request: dict[str, Any],
    fds: list[int],
    imported_env: dict[str, str],
) -> None:
    """In the forked process: become the caller's command, run it, send its exit code, exit."""
    code = 3
    try:
        _reply(conn, {"accepted": True})
        for number in (signal.SIGCHLD, signal.SIGTERM, signal.SIGHUP):
            signal.signal(number, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        # A blocked signal stays blocked through fork and exec: a server started by a tool that
        # blocks SIGINT (a hook runner, a test harness mid-spawn) would make Ctrl-C pend forever.
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
        if listener is not None:
            listener.close()
        _take_streams(request["streams"], fds)
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        own_process()  # as in the caller's own process: the processes the command starts inherit them
        for key, value in imported_env.items():
            os.environ.setdefault(key, value)
        if hasattr(time, "tzset"):
            time.tzset()
        os.umask(int(request["umask"]))
        _take_scheduling(request)
        sys.argv = ["blendspace", *request["argv"]]
        conn.settimeout(None)
        finished = threading.Event()
        threading.Thread(target=_relay_interrupts, args=(conn, finished), daemon=True).start()

        from blendspace_pipeline.cli import run_here

        code = run_here(request["argv"])
        _flush()
        finished.set()
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        _reply(conn, {"exit": code})
    except BaseException as error:
        try:
            sys.stderr.write(f"blendspace server: {type(error).__name__}: {error}\n")
            _flush()
        finally:
            os._exit(3)
    os._exit(code)


def _take_scheduling(request: dict[str, Any]) -> None:
    """The caller's CPUs (`taskset`, a cpuset: `--jobs auto` counts them) and niceness (`nice`
    on a farm). Where the server may not take them (CPUs outside its own cpuset, a priority above
    its own), the command runs with the server's, as it would have without asking."""
    cpus, nice = request.get("cpus"), request.get("nice")
    if cpus and hasattr(os, "sched_setaffinity"):
        with contextlib.suppress(OSError, ValueError):
            os.sched_setaffinity(0, cpus)
    if isinstance(nice, int) and hasattr(os, "nice"):
        with contextlib.suppress(OSError):
            os.nice(nice - os.nice(0))


def _take_streams(streams: list[dict[str, str | None]], fds: list[int]) -> None:
    """The caller's stdin/stdout/stderr become this process's, with the caller's text encodings."""
    received = iter(fds)
    for target, described in enumerate(streams):
        fd = os.open(os.devnull, os.O_RDWR) if described.get("fd") is None else next(received)
        os.dup2(fd, target)
        os.close(fd)
    fds.clear()
    sys.stdin, sys.stdout, sys.stderr = (_text(fd, described) for fd, described in enumerate(streams))


def _text(fd: int, described: dict[str, str | None]) -> io.TextIOWrapper:
    """A text stream on ``fd`` as Python would have opened it in the caller (stderr: line-buffered)."""
    raw = io.FileIO(fd, "r" if fd == 0 else "w", closefd=False)
    buffered = io.BufferedReader(raw) if fd == 0 else io.BufferedWriter(raw)
    return io.TextIOWrapper(
        buffered,
        encoding=described.get("encoding") or "utf-8",
        errors=described.get("errors") or "strict",
        line_buffering=fd == 2 or (fd == 1 and os.isatty(1)),
        write_through=fd == 2,
    )


def _relay_interrupts(conn: socket.socket, finished: threading.Event) -> None:
    """Ctrl-C in the caller (one byte), or the caller gone (end of stream): interrupt the command."""
    try:
        data = conn.recv(1)
    except OSError:
        data = b""
    if not finished.is_set() and (data == INTERRUPT or not data):
        # To the main thread: a process-wide kill may land on this thread, and then the main
        # thread (asleep in a rule, say) would see it only when it next runs Python code.
        main = threading.main_thread().ident
        assert main is not None
        signal.pthread_kill(main, signal.SIGINT)


def _flush() -> None:
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):
            stream.flush()


def serve(idle_timeout: float = DEFAULT_IDLE_TIMEOUT) -> int:
    """Preload, listen and answer until stopped; 0 on a clean stop."""
    # As a command's own process does (`blendspace server start` has set them already; a daemon
    # started some other way gets them too): every served command is forked from here.
    own_process()
    _missing, imported_env = preload()
    from blendspace_pipeline.pipeline.outputs import warm

    with contextlib.suppress(Exception):  # a command that needs them makes them, and reports why not
        warm()
    # Every forked command inherits the allocator settings of the measuring workers: a served
    # `--jobs 1` build measures clips without a page fault per fresh page either.
    from blendspace_pipeline.memory import collect_less, keep_freed_memory

    keep_freed_memory()
    collect_less()
    # Forked commands share the server's memory copy-on-write; the collector walking every object
    # would copy all of it into each command (tens of ms here). Frozen objects are never walked.
    gc.collect()
    gc.freeze()
    server = Server(idle_timeout, imported_env)
    server.bind()
    signal.signal(signal.SIGCHLD, signal.SIG_IGN)  # the kernel reaps finished commands
    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    sys.stderr.write(f"blendspace server: pid {os.getpid()} listening on {server.path}\n")
    sys.stderr.flush()
    try:
        server.loop()
    except KeyboardInterrupt:
        pass
    finally:
        server.release()
    if server.stale:  # the command that noticed ran in its caller; the next ones get the new code
        sys.stderr.write("blendspace server: the installed code changed; starting again\n")
        sys.stderr.flush()
        arguments = ["-m", "blendspace_pipeline.server.daemon", "--idle-timeout", str(idle_timeout)]
        os.execv(sys.executable, [sys.executable, *arguments])
    return 0


def _stop(_number: int, _frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m blendspace_pipeline.server.daemon")
    parser.add_argument("--idle-timeout", type=float, default=DEFAULT_IDLE_TIMEOUT)
    args = parser.parse_args(argv)
    os.chdir(server_dir().anchor or "/")  # never keep a project folder busy
    return serve(args.idle_timeout)


if __name__ == "__main__":
    raise SystemExit(main())
