"""cadence-mismatch and foot-phase-mismatch: on hand-made views, on measured procedural clips, in a build."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
from blendspace_pipeline.rules.cadence_mismatch import CadenceMismatch
from blendspace_pipeline.rules.foot_phase_mismatch import FootPhaseMismatch

from blendspace_pipeline.api import SpaceView
from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import SAMPLE_SET, GaitSpec, generate_planted
from blendspace_pipeline.testing import run_rule, space_from_positions, space_from_specs
from blendspace_pipeline.writers.usd_clip import write_usd_clip


def _with_gaits(space: SpaceView, **gaits: dict[str, object]) -> SpaceView:
    samples = tuple(replace(s, **gaits.get(s.name, {})) for s in space.samples)  # type: ignore[arg-type]
    return replace(space, samples=samples)


POSITIONS = {"walk": (0.0, 1.4), "run": (0.0, 4.0), "run_left": (90.0, 4.0), "idle": (0.0, 0.0)}


def test_cadence_mismatch_reports_edges_beyond_the_threshold() -> None:
    space = _with_gaits(
        space_from_positions(POSITIONS),
        walk={"gait_period": 1.0},
        run={"gait_period": 0.8},
        run_left={"gait_period": 0.5},
    )
    found = run_rule(CadenceMismatch, space)
    pairs = {frozenset(d.clips) for d in found}
    # run 0.8 s vs run_left 0.5 s: 60 %; walk 1.0 s vs run_left: 100 %; walk vs run: 25 % (not beyond).
    assert frozenset({"run", "run_left"}) in pairs
    assert frozenset({"walk", "run"}) not in pairs
    assert all("idle" not in d.clips for d in found)  # no gait, nothing to compare
    finding = next(d for d in found if set(d.clips) == {"run", "run_left"})
    assert "60%" in finding.message and finding.hint and "retime" in finding.hint
    assert finding.position == pytest.approx((45.0, 4.0))
    assert {frozenset(d.clips) for d in run_rule(CadenceMismatch, space, threshold=1.5)} == set()


def test_foot_phase_mismatch_tells_sliding_from_crossed_legs() -> None:
    space = _with_gaits(
        space_from_positions(POSITIONS),
        walk={"plant_phases": {"left": 0.2, "right": 0.7}},
        run={"plant_phases": {"left": 0.25, "right": 0.75}},
        run_left={"plant_phases": {"left": 0.7, "right": 0.2}},
    )
    found = {frozenset(d.clips): d for d in run_rule(FootPhaseMismatch, space)}
    assert frozenset({"walk", "run"}) not in found  # 0.05 of a stride: in step
    crossed = found[frozenset({"run", "run_left"})]
    assert "crosses the legs" in crossed.message and crossed.hint and "re-cut" in crossed.hint


def test_measured_sample_set_flags_the_run_cadences() -> None:
    """The issue's case: run_fwd (0.8 s stride) next to run_turn_left (0.5 s)."""
    space = space_from_specs(SAMPLE_SET)
    periods = {s.name: s.gait_period for s in space.samples}
    assert periods["run_fwd"] == pytest.approx(0.8, rel=0.03)
    assert periods["run_turn_left"] == pytest.approx(0.5, rel=0.03)
    pairs = {frozenset(d.clips) for d in run_rule(CadenceMismatch, space)}
    assert frozenset({"run_fwd", "run_turn_left"}) in pairs


def test_planted_clips_with_other_duty_factors_mismatch_their_plants() -> None:
    # Duty 0.7 plants the left foot at phase 0.15, duty 0.3 at 0.35: 0.2 of a stride apart.
    specs = [
        GaitSpec("walk_long", speed=1.4, duration=2.0),
        GaitSpec("walk_short", speed=1.4, turn_rate=40.0, duration=2.0),
    ]
    space = space_from_positions({"walk_long": (0.0, 1.4), "walk_short": (40.0, 1.4), "idle": (0.0, 0.0)})
    from blendspace_pipeline.motion.clip import forward_kinematics
    from blendspace_pipeline.motion.clip_ops.feet import clip_contacts
    from blendspace_pipeline.motion.clip_ops.phase import detect_cycle
    from blendspace_pipeline.motion.contacts import plant_phases
    from blendspace_pipeline.motion.detect import RigSettings

    gaits = {}
    for spec, duty in zip(specs, (0.7, 0.3), strict=True):
        clip = generate_planted(spec, duty=duty)
        contacts = clip_contacts(
            clip, RigSettings(), forward_kinematics(clip)[1], meters_per_unit=1.0, up_axis="y"
        )
        cycle = detect_cycle(clip, RigSettings())
        assert contacts is not None and cycle is not None
        gaits[spec.name] = {"plant_phases": plant_phases(contacts, cycle.phase, clip.fps)}
    found = run_rule(FootPhaseMismatch, _with_gaits(space, **gaits))
    assert [set(d.clips) for d in found] == [{"walk_long", "walk_short"}]
    assert "slides" in found[0].message


def test_build_reports_cadence_mismatch_and_lists_both_rules(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    specs = [
        GaitSpec("idle", duration=1.0),
        GaitSpec("run_fwd", speed=4.0, duration=0.8, stride_length=2.6),
        GaitSpec("run_turn_left", speed=4.0, turn_rate=90.0, duration=1.0, stride_length=2.6),
        GaitSpec("walk_fwd", speed=1.4, duration=1.0),
    ]
    for spec in specs:
        write_usd_clip(
            generate_planted(spec), tmp_path / "clips" / f"{spec.name}.usda", meters_per_unit=1.0, up_axis="y"
        )
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: gaits\nclips:\n  - path: clips/*.usda\n"
        "axes:\n  x: {feature: turn_rate, min: -90, max: 90, divisions: 18}\n"
        "  y: {feature: speed, min: 0, max: 5, divisions: 50}\n"
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--format", "json", "--no-fix"]) in (0, 1)
    doc = json.loads((out / "gaits.blendspace.json").read_text())
    cadence = [d for d in doc["diagnostics"] if d["rule"] == "cadence-mismatch"]
    assert {frozenset(d["clips"]) for d in cadence} >= {frozenset({"run_fwd", "run_turn_left"})}
    assert all(d["code"] == "BS120" and d["severity"] == "warning" and d["hint"] for d in cadence)
    capsys.readouterr()
    assert main(["rules"]) == 0
    listed = capsys.readouterr().out
    assert "cadence-mismatch" in listed and "foot-phase-mismatch" in listed
