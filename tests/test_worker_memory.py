"""The measuring workers' allocator settings (`measure_stage.keep_freed_memory`): glibc keeps freed
clip-sized blocks for the next clip instead of returning them to the kernel; elsewhere nothing
happens and nothing fails."""

from __future__ import annotations

import ctypes
import platform
import subprocess
import sys

import pytest

from blendspace_pipeline.pipeline import measure_stage

# Measure a 7 s 120 fps take 10 times (what a worker does with every clip) and print the page
# faults it cost: without the settings glibc returns the freed arrays' pages to the kernel and
# the next clip faults them in again.
_PROBE = """
import resource, sys
if sys.argv[1] == "init":
    from blendspace_pipeline.pipeline.measure_stage import keep_freed_memory
    keep_freed_memory()
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate
clip = generate(GaitSpec("take", speed=1.4, turn_rate=30.0, duration=7.0, fps=120.0))
measure(clip, RigSettings())
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):
    measure(clip, RigSettings())
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _faults(mode: str) -> int:
    done = subprocess.run(
        [sys.executable, "-c", _PROBE, mode], capture_output=True, text=True, check=True, timeout=60
    )
    return int(done.stdout.strip())


@pytest.mark.skipif(
    not sys.platform.startswith("linux") or platform.libc_ver()[0] != "glibc", reason="glibc only"
)
def test_a_worker_reuses_freed_clip_sized_blocks() -> None:
    plain, tuned = _faults("plain"), _faults("init")
    # Hundreds of faults per clip on fresh pages; reused pages cost next to none.
    assert plain > 1_000
    assert tuned < plain / 10


def test_elsewhere_it_does_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_library(*_args: object) -> None:
        raise AssertionError("libc must not be opened off Linux")

    monkeypatch.setattr(sys, "platform", "darwin")
    monkeypatch.setattr(ctypes, "CDLL", no_library)
    measure_stage.keep_freed_memory()


def test_a_libc_without_mallopt_is_no_error(monkeypatch: pytest.MonkeyPatch) -> None:
    class Musl:
        def __getattr__(self, name: str) -> object:
            raise AttributeError(name)

    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setattr(ctypes, "CDLL", lambda *_args: Musl())
    measure_stage.keep_freed_memory()
    monkeypatch.setattr(ctypes, "CDLL", lambda *_args: (_ for _ in ()).throw(OSError("no libc")))
    measure_stage.keep_freed_memory()
