"""The measuring workers' allocator settings (`memory.keep_freed_memory`): glibc keeps freed
clip-sized blocks for the next clip instead of returning them to the kernel; elsewhere nothing
happens and nothing fails."""

from __future__ import annotations

import ctypes
import gc
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from blendspace_pipeline import memory

# Measure a 7 s 120 fps take 10 times (what a worker does with every clip) and print the page
# faults it cost: without the settings glibc returns the freed arrays' pages to the kernel and
# the next clip faults them in again.
_PROBE = """
import resource, sys
if sys.argv[1] == "init":
    from blendspace_pipeline.memory import keep_freed_memory
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
    memory.keep_freed_memory()


def test_a_libc_without_mallopt_is_no_error(monkeypatch: pytest.MonkeyPatch) -> None:
    class Musl:
        def __getattr__(self, name: str) -> object:
            raise AttributeError(name)

    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setattr(ctypes, "CDLL", lambda *_args: Musl())
    memory.keep_freed_memory()
    monkeypatch.setattr(ctypes, "CDLL", lambda *_args: (_ for _ in ()).throw(OSError("no libc")))
    memory.keep_freed_memory()


def test_the_command_line_keeps_freed_memory_and_a_library_call_does_not(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`blendspace` is a process of its own (its in-process measuring, --jobs 1, gains the same);
    `main([...])` from a script or a test leaves the caller's allocator alone."""
    from blendspace_pipeline import cli

    calls: list[int] = []
    monkeypatch.setattr(memory, "keep_freed_memory", lambda: calls.append(1))
    monkeypatch.setattr(memory, "collect_less", lambda: calls.append(2))
    monkeypatch.setenv("BLENDSPACE_NO_SERVER", "1")
    monkeypatch.setattr(sys, "argv", ["blendspace", "--version"])

    def ended(code: int) -> None:
        raise SystemExit(code)  # the command's own process ends here, without teardown

    monkeypatch.setattr(cli, "_exit_now", ended)
    with pytest.raises(SystemExit) as exited:
        cli.main()
    assert exited.value.code == 0
    assert calls == [1, 2]
    assert cli.main(["--version"]) == 0
    assert calls == [1, 2]
    assert "blendspace" in capsys.readouterr().out


def test_the_command_collects_young_objects_less_often() -> None:
    """`collect_less`: the youngest generation every `YOUNG_THRESHOLD` allocations instead of
    Python's 700, the older generations' ratios kept."""
    import gc

    before = gc.get_threshold()
    try:
        memory.collect_less()
        assert gc.get_threshold() == (memory.YOUNG_THRESHOLD, before[1], before[2])
        assert before[0] < memory.YOUNG_THRESHOLD
    finally:
        gc.set_threshold(*before)


def test_the_build_server_sets_both_for_the_commands_it_forks(monkeypatch: pytest.MonkeyPatch) -> None:
    """`serve` tunes the allocator and the collector before it listens: every forked command
    inherits both."""
    import gc

    from blendspace_pipeline.server import daemon

    calls: list[str] = []
    monkeypatch.setattr(memory, "keep_freed_memory", lambda: calls.append("allocator"))
    monkeypatch.setattr(memory, "collect_less", lambda: calls.append("collector"))
    monkeypatch.setattr(daemon, "preload", lambda: ([], {}))

    class Refused(Exception):
        pass

    class NoSocket:
        def __init__(self, *_args: object) -> None:
            calls.append("listen")

        def bind(self) -> None:
            raise Refused

    monkeypatch.setattr(daemon, "Server", NoSocket)
    try:
        with pytest.raises(Refused):
            daemon.serve(1.0)
    finally:
        gc.unfreeze()  # serve froze this test process's objects before it would listen
    assert calls == ["allocator", "collector", "listen"]


def test_build_and_check_run_without_the_cycle_collector_and_give_it_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`memory.collector_paused`: the rules of a `build` and a `check` run with the cycle
    collector off (it walked every measurement and finding of a 1,000-clip edit again and again),
    and a caller of `cli.main` gets its collector back, also after a failed command."""
    from blendspace_pipeline.cli import main
    from blendspace_pipeline.motion.procedural import GaitSpec, generate
    from blendspace_pipeline.pipeline import analysis
    from blendspace_pipeline.writers.bvh import write_bvh_clip

    (tmp_path / "clips").mkdir()
    for spec in (
        GaitSpec("walk", speed=1.4),
        GaitSpec("run", speed=3.0),
        GaitSpec("left", speed=1.4, turn_rate=60.0),
    ):
        write_bvh_clip(generate(spec), tmp_path / "clips" / f"{spec.name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    seen: list[bool] = []
    real = analysis.finish_analysis

    def spy(space: object) -> None:
        seen.append(gc.isenabled())
        real(space)  # type: ignore[arg-type]

    monkeypatch.setattr(analysis, "finish_analysis", spy)
    assert gc.isenabled()
    main(["check", str(manifest)])
    main(["build", str(manifest), "--no-fix", "--out", str(tmp_path / "out")])
    assert seen and not any(seen)
    assert gc.isenabled()
    assert main(["build", str(tmp_path / "missing.yaml")]) == 2
    assert gc.isenabled()
    gc.disable()  # a caller that runs without it keeps it off
    try:
        main(["check", str(manifest)])
        assert not gc.isenabled()
    finally:
        gc.enable()
