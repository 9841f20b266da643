"""Run independent tasks (the output writers) in forked processes, failing exactly as serial runs do.

With ``jobs`` > 1 where `os.fork` exists, each task runs in a child forked from this process: it
inherits the document and the space (nothing is pickled to it) and writes its own file. At most
``jobs`` children run at once, started in ``start_order`` (the longest first).
Every child is waited for before this returns or raises, so a caller that removes its staging
folder on failure never races a child still writing into it.

Failures reach the caller as if the tasks had run here one after another: when several fail, the
error of the first failing task in the given order is raised (a serial run would have stopped
there), as the same exception type with the same message (it is pickled back to the parent; one
that cannot be is rebuilt as an exception of the same class name and text, so the CLI prints the
same line). The child's traceback is attached as a note, so the crash log still shows where it
failed. A child that dies without a word (a signal, the OOM killer) is an internal error.

Without fork, with ``jobs`` 1, or with one task, the tasks run here in order, as before.

A task may return a value (`results_of`): it is pickled back, so it should be small (a set of
finding keys, a number), never a clip.
"""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
import selectors
import signal
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures.process import BrokenProcessPool
from typing import Any

Task = Callable[[], Any]
_VALUE = b"\x00"  # a result payload that is a returned value (a pickled error starts with 0x80)


def can_fork() -> bool:
    return hasattr(os, "fork") and sys.platform != "win32"


class WorkerLost(RuntimeError):
    """A pool's worker ended without an answer (the out-of-memory killer, a crash in a native
    library): an internal error (exit 3) whose one line says what to do instead of
    `BrokenProcessPool`."""


@contextlib.contextmanager
def explained_worker_loss(work: str) -> Iterator[None]:
    """Around a `ProcessPoolExecutor`'s results: its `BrokenProcessPool` as a `WorkerLost` that
    names the ``work`` ("measuring", "foot-skate") and the way out."""
    try:
        yield
    except BrokenProcessPool as error:
        raise WorkerLost(
            f"a {work} process ended without an answer (killed, for example by the system when "
            "memory runs out, or crashed); run again with fewer --jobs, or --jobs 1 to do the "
            "work in the command's own process"
        ) from error


def guided_chunks(count: int, workers: int, most: int) -> list[tuple[int, int]]:
    """(first, last) index ranges covering ``count`` work items in order, for a pool of ``workers``:
    each a quarter of the remaining items' share per worker, at most ``most`` and at least 1
    (guided self-scheduling). A worker that got less CPU (the command's own process and writers
    share the cores) takes fewer chunks, and the last chunks are single items, so the workers end
    within about one item of each other. Equal chunks (16 clips; half of the foot-skate map each)
    left one worker at the end alone for up to 0.1 s of a cold 1,000-clip build (0.2 s for the
    map)."""
    ranges, first = [], 0
    while first < count:
        size = max(1, min(most, -(-(count - first) // (4 * workers))))
        ranges.append((first, first + size))
        first += size
    return ranges


def run_tasks(tasks: Sequence[Task], jobs: int, start_order: Sequence[int] | None = None) -> None:
    """Run every task; raise the first failing task's error (in ``tasks`` order, the serial one).
    ``start_order``: the indices of ``tasks`` in the order children start (longest first)."""
    if jobs < 2 or len(tasks) < 2 or not can_fork():
        for task in tasks:
            task()
        return
    with Children(tasks, jobs, start_order) as children:
        errors = children.wait()
    if errors:
        raise errors[min(errors)]


def results_of(tasks: Sequence[Task], jobs: int, meanwhile: Callable[[], None] | None = None) -> list[Any]:
    """Every task's return value, in order: the first here, the others in up to ``jobs`` - 1
    forked children meanwhile. Errors as `run_tasks` raises them (the serial order decides).

    ``meanwhile``: work of this process's own that does not depend on the tasks (it must not
    raise). Given, every task runs in a child (up to ``jobs`` at once) and this process does it
    while they run; without children it runs first, here."""
    if jobs < 2 or len(tasks) < 2 or not can_fork():
        if meanwhile is not None:
            meanwhile()
        return [task() for task in tasks]
    if meanwhile is not None:
        with Children(tasks, jobs) as children:
            meanwhile()
            errors = children.wait()
        if errors:
            raise errors[min(errors)]
        return [children.results.get(index) for index in range(len(tasks))]
    with Children(tasks[1:], jobs - 1) as children:
        first = tasks[0]()  # a failure here is the serial one: leaving the block kills the others
        errors = children.wait()
    if errors:
        raise errors[min(errors)]
    return [first] + [children.results.get(index) for index in range(len(tasks) - 1)]


class Children:
    """``tasks`` in forked children, started at once (at most ``limit`` at a time; the others
    start as running ones finish while `wait` waits). Leaving the ``with`` block kills and reaps
    any child still running (the caller failed or was interrupted: none writes on)."""

    def __init__(self, tasks: Sequence[Task], limit: int, start_order: Sequence[int] | None = None):
        self.tasks = list(tasks)
        self.limit = max(1, limit)
        self.errors: dict[int, BaseException] = {}
        self.results: dict[int, Any] = {}  # what a task returned, when it is not None
        self.running: dict[int, tuple[int, int, bytearray]] = {}  # read end -> (index, pid, bytes)
        self.waiting = list(start_order) if start_order is not None else list(range(len(self.tasks)))
        assert sorted(self.waiting) == list(range(len(self.tasks))), "start_order must name every task once"
        try:
            self._fill()
        except BaseException:  # fork refused (EAGAIN): the children already started stop too
            self.kill()
            raise

    def _fill(self) -> None:
        while self.waiting and len(self.running) < self.limit:
            index = self.waiting.pop(0)
            read_end, pid = _start(self.tasks[index])
            self.running[read_end] = (index, pid, bytearray())

    def wait(self) -> dict[int, BaseException]:
        """Wait for every task; their errors by task index (empty when all succeeded)."""
        while self.waiting or self.running:
            self._fill()
            # `selectors` (poll/epoll), not `select.select`: a long-lived process (a build server)
            # may hold descriptors above select's 1024 limit.
            with selectors.DefaultSelector() as selector:
                for read_end in self.running:
                    selector.register(read_end, selectors.EVENT_READ)
                ready = [key.fd for key, _ in selector.select()]
            for read_end in ready:
                index, pid, data = self.running[read_end]
                chunk = os.read(read_end, 1 << 16)
                if chunk:
                    data += chunk
                    continue
                del self.running[read_end]  # end of file: the child is done
                os.close(read_end)
                error, value = _finish(pid, bytes(data))
                if error is not None:
                    self.errors[index] = error
                elif value is not None:
                    self.results[index] = value
        return self.errors

    def ready(self) -> bool:
        """Whether every task has finished (nothing left to start, and each running child has
        closed its pipe or begun writing its result, which it does once its task returned)."""
        if self.waiting:
            return False
        with selectors.DefaultSelector() as selector:
            for read_end in self.running:
                selector.register(read_end, selectors.EVENT_READ)
            return len(selector.select(timeout=0)) == len(self.running) if self.running else True

    def kill(self) -> None:
        self.waiting.clear()
        for read_end, (_, pid, _) in self.running.items():
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(OSError):
                os.waitpid(pid, 0)
            with contextlib.suppress(OSError):
                os.close(read_end)
        self.running.clear()

    def __enter__(self) -> Children:
        return self

    def __exit__(self, *exc: object) -> None:
        self.kill()


def _start(task: Task) -> tuple[int, int]:
    """Fork a child running ``task``; return the read end of its result pipe and its pid."""
    # Buffered text would otherwise be written twice: by the parent and by the child's copy.
    sys.stdout.flush()
    sys.stderr.flush()
    read_end, write_end = os.pipe()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: never returns, never runs the parent's cleanup (`finally`, atexit)
        status = 1
        try:
            # The inherited objects are the parent's: a collection here would walk (and so copy,
            # page by page) the whole inherited heap; only what the task makes is collected.
            gc.freeze()
            os.close(read_end)
            _die_with_parent(parent)
            payload = _result_of(task)
            view = memoryview(payload)
            while view:
                view = view[os.write(write_end, view) :]
            sys.stdout.flush()
            sys.stderr.flush()
            status = 0
        finally:
            os._exit(status)
    os.close(write_end)
    return read_end, pid


def _result_of(task: Task) -> bytes:
    """b"" when ``task`` succeeded and returned None, `_VALUE` and the value pickled when it
    returned one, else its exception pickled (or a stand-in that pickles)."""
    try:
        value = task()
        if value is not None:
            return _VALUE + pickle.dumps(value)
    except BaseException as error:  # every failure goes back to the parent, exit codes decided there
        detail = "".join(traceback.format_exception(error))
        try:
            payload = pickle.dumps(error)
            back = pickle.loads(payload)
            if type(back) is not type(error) or str(back) != str(error):
                raise TypeError("does not survive pickling")
        except Exception:
            payload = pickle.dumps((type(error).__name__, str(error), detail))
        return pickle.dumps((payload, detail))
    return b""


def _finish(pid: int, data: bytes) -> tuple[BaseException | None, Any]:
    """Reap the child ``pid``; its error (None when it succeeded) and the value it returned."""
    _, status = os.waitpid(pid, 0)
    exited = os.waitstatus_to_exitcode(status) == 0
    if not data or (data.startswith(_VALUE) and not exited):
        if exited:
            return None, None
        return RuntimeError(f"a writer process ended without a result ({_how(status)})"), None
    if data.startswith(_VALUE):
        return None, pickle.loads(data[len(_VALUE) :])
    payload, detail = pickle.loads(data)
    error = pickle.loads(payload)
    if isinstance(error, tuple):  # did not pickle: the same class name and text
        name, text, _ = error
        error = type(name, (Exception,), {})(text)
    assert isinstance(error, BaseException)
    error.add_note(f"raised in a forked writer process:\n{detail}")
    return error, None


def _how(status: int) -> str:
    if os.WIFSIGNALED(status):
        return f"killed by signal {os.WTERMSIG(status)}"
    return f"exit status {os.waitstatus_to_exitcode(status)}"


def _die_with_parent(parent: int) -> None:
    """Linux: a child whose build was killed (kill -9) stops instead of writing on unseen."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)
