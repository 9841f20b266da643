"""The clips `test_measure_golden.py` pins, and the script that recorded their measurements.

Speeding `motion.measure.measure` up must not change a number it produces. This module builds a
spread of clips that takes every branch of measurement (procedural walks, runs, arcs, strafes,
spins and idles in Y and Z up, several units, a ground-level root joint, T-pose first frames,
files that state no unit or up axis, rigs without recognisable hips or without a hierarchy,
hostile studio-like takes with starts, stops and pelvis sway, manifest overrides, explicit and
``auto`` ranges) plus the CMU takes of shared/data, and records each one's full `Measurement`
(features, contacts, plant phases, notes, guesses...) and its `detect_cycle` into
``tests/measurement_golden.json``.

    python tests/measurement_golden.py   # re-record (only when a number changes on purpose,
                                         # with the measurement revision in pipeline/cache.py bumped)
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterator
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

import numpy as np

from blendspace_pipeline.motion import hostile
from blendspace_pipeline.motion.clip import Clip, Skeleton
from blendspace_pipeline.motion.clip_ops.phase import detect_cycle
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import TimeRange, measure
from blendspace_pipeline.motion.procedural import GaitSpec, generate, generate_planted

FIXTURE = Path(__file__).with_name("measurement_golden.json")
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
AUTO = RigSettings()


def _as_file(clip: Clip) -> Clip:
    """The clip as a BVH would read: no unit and no up axis stated, so both are detected."""
    return replace(clip, meters_per_unit=None, up_axis=None)


def _anonymous(clip: Clip) -> Clip:
    """The same motion on joints named J0, J1...: no hips, feet or head to recognise."""
    names = tuple(f"J{i}" for i in range(clip.skeleton.joint_count))
    return replace(clip, skeleton=replace(clip.skeleton, names=names))


def _flat(clip: Clip) -> Clip:
    """The tracks without their hierarchy (as a Godot Animation resource carries them)."""
    return replace(clip, skeleton=replace(clip.skeleton, has_hierarchy=False))


def _renamed_hips(clip: Clip) -> Clip:
    """Hips under names no rule recognises, for the manifest's `left_hip`/`right_hip`."""
    names = [
        "PelvisL_socket" if n == "LeftUpLeg" else "PelvisR_socket" if n == "RightUpLeg" else n
        for n in clip.skeleton.names
    ]
    skeleton: Skeleton = replace(clip.skeleton, names=tuple(names))
    return replace(clip, skeleton=skeleton)


Case = tuple[str, Callable[[], Clip], RigSettings, TimeRange]


def _procedural_cases() -> Iterator[Case]:
    specs = [
        GaitSpec("idle", duration=1.0),
        GaitSpec("walk", speed=1.4, duration=1.2),
        GaitSpec("walk120", speed=1.5, duration=7.0, fps=120.0, turn_rate=10.0),
        GaitSpec("run", speed=4.0, duration=1.0, stride_length=2.6),
        GaitSpec("arc_left", speed=1.2, turn_rate=60.0, duration=1.5),
        GaitSpec("arc_right", speed=1.2, turn_rate=-120.0, duration=1.5, fps=60.0),
        GaitSpec("spin", turn_rate=360.0, duration=1.0),
        GaitSpec("strafe_left", speed=1.2, direction=90.0, duration=1.0, stride_length=1.0),
        GaitSpec("backward", speed=1.1, direction=180.0, duration=1.0),
        GaitSpec("diagonal", speed=1.3, direction=-135.0, duration=2.0, start_heading=37.0),
        GaitSpec("short", speed=1.4, duration=0.2),
        GaitSpec("swagger", speed=1.4, duration=3.0, pelvis_yaw=25.0, fps=60.0),
    ]
    for spec in specs:
        yield spec.name, lambda spec=spec: generate(spec), AUTO, None
    walk = GaitSpec("walk_long", speed=1.4, duration=4.0, fps=60.0, turn_rate=-20.0)
    yield "walk_z_cm", lambda: generate(walk, up="z", meters_per_unit=0.01), AUTO, None
    yield "walk_root_joint", lambda: generate(walk, with_root_joint=True, root_yaw_offset=90.0), AUTO, None
    yield "walk_tpose", lambda: generate(walk, tpose_first_frame=True), AUTO, None
    yield "walk_file_y_cm", lambda: _as_file(generate(walk, meters_per_unit=0.01)), AUTO, None
    yield "walk_file_z_mm", lambda: _as_file(generate(walk, up="z", meters_per_unit=0.001)), AUTO, None
    yield "walk_file_tpose", lambda: _as_file(generate(walk, tpose_first_frame=True)), AUTO, None
    yield "walk_range", lambda: generate(walk), AUTO, (0.5, 3.25)
    yield "walk_range_from0", lambda: generate(walk, tpose_first_frame=True), AUTO, (0.0, 2.0)
    yield "walk_auto", lambda: generate(walk), AUTO, "auto"
    yield "walk_anonymous", lambda: _anonymous(_as_file(generate(walk))), AUTO, None
    yield "walk_anonymous_root_joint", lambda: _anonymous(generate(walk, with_root_joint=True)), AUTO, None
    yield "walk_flat", lambda: _flat(_as_file(generate(walk))), AUTO, None
    yield (
        "walk_units_cm",
        lambda: _as_file(generate(walk, meters_per_unit=0.01)),
        RigSettings(units="cm"),
        None,
    )
    yield "walk_units_number", lambda: generate(walk), RigSettings(units=0.5, up="y"), None
    yield "walk_tpose_drop", lambda: generate(walk), RigSettings(tpose="drop"), None
    yield "walk_tpose_keep", lambda: generate(walk, tpose_first_frame=True), RigSettings(tpose="keep"), None
    hips = RigSettings(left_hip="PelvisL_socket", right_hip="PelvisR_socket")
    yield "walk_named_hips", lambda: _renamed_hips(_as_file(generate(walk))), hips, None
    yield "walk_one_hip", lambda: generate(walk), RigSettings(left_hip="LeftUpLeg"), None
    rooted = RigSettings(root="Root", forward="+z")
    yield "walk_root_forward", lambda: generate(walk, with_root_joint=True), rooted, None
    yield "walk_root_only", lambda: generate(walk, with_root_joint=True), RigSettings(root="Root"), None
    yield "walk_forward_only", lambda: generate(walk), RigSettings(forward="-x"), None
    planted = GaitSpec("planted", speed=1.3, duration=3.0, fps=60.0, turn_rate=15.0)
    yield "planted", lambda: generate_planted(planted), AUTO, None
    yield (
        "planted_z_file",
        lambda: _as_file(generate_planted(planted, up="z", meters_per_unit=0.01)),
        AUTO,
        None,
    )


def _hostile_cases() -> Iterator[Case]:
    grid = hostile.grid()
    for spec in grid[::7]:
        yield f"hostile_{spec.name}", lambda spec=spec: hostile.take(spec).clip, AUTO, None
    for spec in grid[3::13]:
        yield f"hostile_{spec.name}_auto", lambda spec=spec: hostile.take(spec).clip, AUTO, "auto"
    for spec in hostile.studio_set()[:8]:
        yield f"studio_{spec.name}", lambda spec=spec: hostile.take(spec).clip, AUTO, None


def _read(*parts: str) -> Callable[[], Clip]:
    def read() -> Clip:
        from blendspace_pipeline.readers import read_clips

        return read_clips(SHARED_DATA.joinpath(*parts))[0]

    return read


def shared_cases() -> Iterator[Case]:
    """Real takes from ../shared/data (the test skips them when the folder is absent)."""
    for take in ("131_01.bvh", "131_02.bvh"):
        yield f"cmu_{take}", _read("cmu", take), AUTO, None
        yield f"cmu_{take}_auto", _read("cmu", take), AUTO, "auto"
        yield f"cmu_{take}_range", _read("cmu", take), AUTO, (1.0, 5.5)
    yield "fox", _read("khronos-fox", "Fox.glb"), AUTO, None
    for name in ("walking_nogun-cycle.tres", "strafe_left-cycle.tres"):
        yield f"godot_{name}", _read("godot-tps-demo", name), AUTO, None


def generated_cases() -> Iterator[Case]:
    yield from _procedural_cases()
    yield from _hostile_cases()


def _cycle_record(clip: Clip, settings: RigSettings) -> dict[str, Any] | None:
    cycle = detect_cycle(clip, settings)
    if cycle is None:
        return None
    samples = np.linspace(0, len(cycle.phase) - 1, min(50, len(cycle.phase))).round().astype(int)
    return {
        "period": cycle.period,
        "fit": cycle.fit,
        "feet": list(cycle.feet),
        "loop_strides": cycle.loop_strides,
        "open_loop": cycle.open_loop,
        "phase_sum": float(cycle.phase.sum()),
        "phase_samples": [float(v) for v in cycle.phase[samples]],
    }


def record(clip: Clip, settings: RigSettings, time_range: TimeRange) -> dict[str, Any]:
    """What a case pins: the whole measurement (as JSON would hold it) and the gait cycle."""
    measured = json.loads(json.dumps(asdict(measure(clip, settings, time_range))))
    return {"measurement": measured, "cycle": _cycle_record(clip, settings)}


def main() -> None:
    cases = list(generated_cases())
    if SHARED_DATA.exists():
        cases += list(shared_cases())
    else:
        sys.exit(f"{SHARED_DATA} is missing: the fixture must pin the real takes too")
    names = [name for name, *_ in cases]
    assert len(names) == len(set(names)), "case names must be unique"
    recorded = {name: record(build(), settings, time_range) for name, build, settings, time_range in cases}
    FIXTURE.write_text(json.dumps(recorded, indent=1, sort_keys=True) + "\n")
    print(f"recorded {len(recorded)} clips into {FIXTURE}")


if __name__ == "__main__":
    main()
