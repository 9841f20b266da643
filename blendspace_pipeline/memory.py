"""How a short-lived process that measures clips takes memory from glibc (`keep_freed_memory`),
and how often its cycle collector runs (`collect_less`).

Not for library callers: `blendspace_pipeline.api` never changes the allocator of the process
it runs in. The measuring workers, the build server and the `blendspace` command line do.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import sys
from collections.abc import Iterator

# Objects allocated (net) between two collections of the youngest generation; Python's default is 700.
YOUNG_THRESHOLD = 10_000
# glibc mallopt parameters (malloc.h).
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
# A 7 s take's arrays are 0.1-0.5 MB each and a 300 s take's ~20 MB: all below this stay on the heap.
_MMAP_THRESHOLD = 32 * 1024 * 1024  # glibc's largest allowed value on 64-bit
_TRIM_THRESHOLD = 128 * 1024 * 1024
_TOP_PAD = 16 * 1024 * 1024


def keep_freed_memory() -> None:
    """Keep freed memory in this process's heap: a measuring worker's, the build server's or a
    `blendspace` command's (glibc only; elsewhere nothing happens).

    By default glibc hands every block of 128 kB and more (a clip's file, its rotations, its
    forward kinematics...) straight back to the kernel when freed, and trims the heap's top, so
    the next clip's arrays land on fresh pages and every 4 kB page faults on first touch: ~500
    faults and ~2 ms of system time per 7 s take here, ~2 s per 1,000 clips. With these settings
    the worker reuses its own pages: on the 1,000-clip library of `benchmarks/bench_build.py`,
    ~1 fault per clip instead of 100-500, and a cold `build --jobs 2` spent 2.1-2.4 s of system
    time instead of 4.1-4.5 s, with no more user time (tested: `tests/test_worker_memory.py`). A
    worker is short-lived and measures clips of similar size, so the heap it keeps is about one
    clip's worth. The values measured are the same: only where memory comes from changes.
    """
    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version  # noqa: B018 - glibc only: musl's mallopt ignores these
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    for parameter, value in (
        (_M_MMAP_THRESHOLD, _MMAP_THRESHOLD),
        (_M_TRIM_THRESHOLD, _TRIM_THRESHOLD),
        (_M_TOP_PAD, _TOP_PAD),
    ):
        mallopt(parameter, value)  # 0 on a value this glibc refuses: then its default stays


def collect_less() -> None:
    """Run the cycle collector less often in a `blendspace` command's process (and the build
    server's, whose commands inherit it): the youngest generation is collected every
    `YOUNG_THRESHOLD` allocations instead of 700, the older ones as often relative to it.

    A build's pipeline makes few reference cycles but many objects (a 1,000-clip library's
    measurements, findings and document). With the default thresholds, young collections ran
    every 700 allocations and a full one, walking all of those objects and every imported
    module, whenever the survivors had grown by a quarter: the collector's time in a cold 1,000-clip build's own
    process went from 0.29 s to 0.11 s at `--jobs 1` and from 0.45-0.49 s to 0.12 s at `--jobs 2`
    (where it took CPU from the measuring workers), and in a build with every clip cached from
    0.25 s to 0.09 s. Peak memory was the same (180 MB here, 188 MB in a worker): cycles are still
    collected, a little later. Not for library callers, like `keep_freed_memory`."""
    _young, middle, old = gc.get_threshold()
    gc.set_threshold(YOUNG_THRESHOLD, middle, old)


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """No cycle collection while a `build` or `check` runs; as it was afterwards (a caller of
    `cli.main` in a long-lived process gets its collector back).

    Such a command makes almost no reference cycles: a cold 1,000-clip build left 1,688
    unreachable objects (340 with the collector on), and its peak memory was the same (413 MB
    at `--jobs 1`, 182 MB at `--jobs 2`). But it makes several hundred thousand objects that
    live to its end (measurements, sample views, findings, the document), and every young and
    middle collection walked them: 60-100 ms of a served one-clip edit of that library, in the
    command's own process alone, and more in the writers it forks (which inherit the pause).
    `index`, which runs for hours on a Dask cluster, keeps its collector."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
