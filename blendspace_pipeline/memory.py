"""How a short-lived process that measures clips takes memory from glibc (`keep_freed_memory`).

Not for library callers: `blendspace_pipeline.api` never changes the allocator of the process
it runs in. The measuring workers, the build server and the `blendspace` command line do.
"""

from __future__ import annotations

import ctypes
import sys

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
