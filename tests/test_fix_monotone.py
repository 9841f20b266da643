"""Fixes and placeholders never make a space worse: the cases of issue 11, with their numbers.

Procedural clips (known by construction) and the two CMU takes from shared/data.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import pytest
from blendspace_pipeline.rules.crossing_axis import CrossingAxis
from blendspace_pipeline.rules.uncovered_area import UncoveredArea
from conftest import shared_data
from test_fixes import DRAFT, _bvh_project, _project

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.readers.provenance import Provenance, read_provenance
from blendspace_pipeline.testing import run_rule, space_from_specs
from blendspace_pipeline.writers.bvh import write_bvh_clip
from blendspace_pipeline.writers.gltf import write_gltf_clip
from blendspace_pipeline.writers.usd_clip import write_usd_clip

WALKS = (GaitSpec("walk_12", speed=1.2), GaitSpec("walk_13", speed=1.3), GaitSpec("walk_14", speed=1.4))


def _run(manifest: Path, out: Path, *args: str) -> dict[str, object]:
    with contextlib.redirect_stdout(io.StringIO()):
        code = main(["build", str(manifest), "--out", str(out), "--format", "json", *args])
    assert code in (0, 1)
    name = manifest.read_text().split("name: ")[1].split("\n")[0]
    return json.loads((out / f"{name}.blendspace.json").read_text())  # type: ignore[no-any-return]


def _count(doc: dict[str, object], severity: str, rule: str | None = None) -> int:
    return sum(
        d["severity"] == severity and (rule is None or d["rule"] == rule)
        for d in doc["diagnostics"]  # type: ignore[attr-defined]
    )


def _names(doc: dict[str, object]) -> set[str]:
    return {s["name"] for s in doc["samples"]}  # type: ignore[attr-defined]


def test_three_authored_walks_are_not_merged_away(tmp_path: Path) -> None:
    """1.2 / 1.3 / 1.4 m/s walks with too_close: merge. walk_13 sits at the cluster's centre: it
    used to be taken for an earlier merge and its neighbours deleted (0 errors became 3)."""
    specs = (*DRAFT, *WALKS)
    before = _run(_project(tmp_path / "a", specs), tmp_path / "oa", "--no-fix")
    after = _run(_project(tmp_path / "b", specs, "fixes: {too_close: merge}\n"), tmp_path / "ob")
    # Before: the draft lacks turn_in_place_right (2 crossing errors); the mirror fix makes it.
    assert _count(before, "error") == 2 and _count(after, "error") == 0
    assert {"walk_12", "walk_13", "walk_14"} <= _names(after)
    assert not any(s["fix"] == "too-close" for s in after["samples"])  # type: ignore[attr-defined]
    [rejected] = [d for d in after["diagnostics"] if d["rule"] == "fix-rejected"]  # type: ignore[attr-defined]
    assert rejected["code"] == "BS907" and rejected["severity"] == "info"
    assert "walk_13 (on the turn_rate = 0 axis)" in rejected["message"]
    # The mirror fix still made turn_in_place_right: the axis-clip fix is not blocked either.
    assert "turn_in_place_right" in _names(after)
    # too-close gets its merge placeholder (the paper's green marker) where the merge would go.
    [mark] = [p for p in after["placeholders"] if p["rule"] == "too-close"]  # type: ignore[attr-defined]
    assert mark["priority"] == "suggested"
    assert mark["position"] == pytest.approx([0.0, 1.3], abs=0.01)
    # The sources are untouched on disk.
    assert sorted(p.name for p in (tmp_path / "b" / "clips").iterdir()) == sorted(
        f"{s.name}.usda" for s in specs
    )


def test_keep_representative_keeps_the_key_forward_clip(tmp_path: Path) -> None:
    """run_fast (4.2 m/s) is the top of the speed axis; keep-representative used to drop it."""
    specs = (*DRAFT, GaitSpec("run_fast", speed=4.2, duration=0.8, stride_length=2.6))
    doc = _run(_project(tmp_path, specs, "fixes: {too_close: keep-representative}\n"), tmp_path / "out")
    assert {"run_fast", "run_fwd"} <= _names(doc)
    assert not any(d["rule"] == "fix-removed" for d in doc["diagnostics"])  # type: ignore[attr-defined]
    [rejected] = [
        d
        for d in doc["diagnostics"]  # type: ignore[attr-defined]
        if d["rule"] == "fix-rejected" and "too-close" in d["message"]
    ]
    assert "run_fast" in rejected["message"] and "never drops a key clip" in rejected["message"]


def test_keep_representative_still_drops_a_clip_that_is_no_key(tmp_path: Path) -> None:
    specs = (
        *DRAFT,
        GaitSpec("walk_a", speed=1.4, turn_rate=25.0),
        GaitSpec("walk_b", speed=1.5, turn_rate=28.0),
    )
    doc = _run(_project(tmp_path, specs, "fixes: {too_close: keep-representative}\n"), tmp_path / "out")
    assert ("walk_a" in _names(doc)) != ("walk_b" in _names(doc))
    assert _count(doc, "warning", "too-close") == 0


def test_cmu_takes_on_narrow_axes_keep_every_clip(tmp_path: Path) -> None:
    """Two CMU takes (a steady range and the whole take each) on narrow axes with straighten and
    merge: 3 of the 4 clips used to be dropped and the space went degenerate."""
    data = shared_data("cmu", "131_01.bvh").parent
    manifest = tmp_path / "manifest.yaml"
    text = (
        "schema_version: 1\nname: cmu\nskeleton: {units: 0.0564}\nclips:\n"
        f"  - path: '{data}/131_01.bvh'\n    name: walk_01\n    range: [2.0, 6.0]\n"
        f"  - path: '{data}/131_02.bvh'\n    name: walk_02\n    range: [3.0, 7.0]\n"
        f"  - path: '{data}/131_01.bvh'\n    name: whole_01\n"
        f"  - path: '{data}/131_02.bvh'\n    name: whole_02\n"
        "axes:\n  x: {feature: turn_rate, min: -5, max: 5, divisions: 20}\n"
        "  y: {feature: speed, min: 0, max: 2, divisions: 40}\n"
    )
    manifest.write_text(text)
    before = _run(manifest, tmp_path / "a", "--no-fix")
    manifest.write_text(text + "fixes: {straighten: true, too_close: merge}\n")
    after = _run(manifest, tmp_path / "b")
    # Every authored clip stays, itself or (straighten: true asks for it) as its straightened copy.
    names = _names(after)
    for clip in ("walk_01", "walk_02", "whole_01", "whole_02"):
        assert clip in names or f"{clip}_straight" in names, clip
    assert _count(after, "error") <= _count(before, "error")
    assert _count(after, "error", "degenerate-space") == 0
    refused = [d for d in after["diagnostics"] if d["rule"] == "fix-rejected"]  # type: ignore[attr-defined]
    # The mirror of whole_02 would add an error (its mirror's edge crosses the turn axis): refused.
    [worse] = [d for d in refused if d["clips"] == ["whole_02"]]
    counts = re.search(r"errors (\d+) → (\d+)", worse["message"])
    assert counts is not None and int(counts[2]) > int(counts[1]), worse["message"]


def test_acute_placeholders_add_no_finding(tmp_path: Path) -> None:
    """Clips authored at the suggested acute-triangle placeholders must not add findings (they
    used to turn 2 acute findings into 4 acute + 2 too-close)."""
    specs = (*DRAFT, GaitSpec("turn_in_place_right", turn_rate=-90.0, duration=2.0), *WALKS)
    first = _run(_project(tmp_path / "a", specs), tmp_path / "oa", "--no-fix")
    marks = [p for p in first["placeholders"] if p["rule"] == "acute-triangle"]  # type: ignore[attr-defined]
    assert len(marks) == 2
    added = tuple(
        GaitSpec(f"added_{i}", speed=p["position"][1], turn_rate=p["position"][0], duration=1.5)
        for i, p in enumerate(marks)
    )
    second = _run(_project(tmp_path / "b", specs + added), tmp_path / "ob", "--no-fix")
    assert _count(second, "warning", "too-close") == _count(first, "warning", "too-close") == 1
    assert _count(second, "warning", "acute-triangle") == _count(first, "warning", "acute-triangle") - 2
    assert _count(second, "error") == 0
    # The four slivers among the walks cannot be cured by one clip: said so, with no marker.
    stuck = [d for d in second["diagnostics"] if d["rule"] == "acute-triangle"]  # type: ignore[attr-defined]
    assert len(stuck) == 4
    assert all("no single added clip removes this finding" in d["hint"] for d in stuck)


def test_turn_in_place_key_clips_sit_at_the_authored_extreme() -> None:
    """Turns in place at +-90 deg/s are the authored extremes: the key clips are there, not at
    +-45 (half the axis range) as before."""
    space = space_from_specs(
        [
            GaitSpec("idle", duration=1.0),
            GaitSpec("walk_left", speed=1.4, turn_rate=50.0, duration=1.0),
            GaitSpec("walk_right", speed=1.4, turn_rate=-50.0, duration=1.0),
            GaitSpec("tip_left", turn_rate=90.0, duration=2.0),
        ]
    )
    findings = run_rule(CrossingAxis, space)
    keys = sorted(round(p.position[0], 6) for f in findings if not f.clips for p in f.placeholders)
    assert -90.0 in keys and 45.0 not in keys and -45.0 not in keys
    full = space_from_specs(
        [
            GaitSpec("idle", duration=1.0),
            GaitSpec("walk", speed=1.4, duration=1.0),
            GaitSpec("walk_left", speed=1.4, turn_rate=50.0, duration=1.0),
            GaitSpec("walk_right", speed=1.4, turn_rate=-50.0, duration=1.0),
            GaitSpec("tip_left", turn_rate=90.0, duration=2.0),
            GaitSpec("tip_right", turn_rate=-90.0, duration=2.0),
        ]
    )
    assert not any(not f.clips for f in run_rule(CrossingAxis, full))  # every key clip is held


def test_uncovered_area_suggests_no_impossible_corner(tmp_path: Path) -> None:
    """The default axes (+-180 deg/s, -3..6 m/s) used to get clips suggested at (180, 6) and
    (-180, -3): motions no actor can perform."""
    doc = _run(_project(tmp_path, DRAFT), tmp_path / "out", "--no-fix")
    [finding] = [d for d in doc["diagnostics"] if d["rule"] == "uncovered-area"]  # type: ignore[attr-defined]
    assert "narrow turn_rate to [-90, 90], speed to [-1.1, 4]" in finding["message"]
    marks = [p["position"] for p in doc["placeholders"] if p["rule"] == "uncovered-area"]  # type: ignore[attr-defined]
    assert marks
    for x, y in marks:
        assert abs(x) <= 90.0 + 1e-6 and -1.1 - 1e-3 <= y <= 4.0 + 1e-3
        # Turn rate shrinks as speed grows: 7 m/s^2 centripetal at most.
        if abs(y) > 0:
            assert abs(x) <= 180 / 3.141592653589793 * 7.0 / abs(y) + 1e-6
    space = space_from_specs(list(DRAFT))
    [direct] = run_rule(UncoveredArea, space)
    assert "narrow" in direct.message


@pytest.mark.parametrize("suffix", [".usda", ".bvh", ".glb", ".gltf"])
def test_provenance_round_trips_in_every_format(tmp_path: Path, suffix: str) -> None:
    clip = generate(GaitSpec("walk", speed=1.4))
    record = Provenance(
        "too-close", ("walk_a", "walk_b"), (0.5, 0.5), "blendspace-pipeline", "0.1.0", "merge"
    )
    path = tmp_path / f"walk{suffix}"
    if suffix == ".usda":
        write_usd_clip(clip, path, meters_per_unit=1.0, up_axis="y", provenance=record)
    elif suffix == ".bvh":
        write_bvh_clip(clip, path, provenance=record)
    else:
        write_gltf_clip(clip, path, meters_per_unit=1.0, up_axis="y", provenance=record)
    assert read_provenance(path) == record
    # The file still reads as a clip (the BVH record is a comment after the frames).
    [back] = read_clips(path)
    assert back.frame_count == clip.frame_count
    plain = tmp_path / f"plain{suffix}"
    if suffix == ".bvh":
        write_bvh_clip(clip, plain)
    elif suffix == ".usda":
        write_usd_clip(clip, plain, meters_per_unit=1.0, up_axis="y")
    else:
        write_gltf_clip(clip, plain, meters_per_unit=1.0, up_axis="y")
    assert read_provenance(plain) is None


def test_generated_clips_carry_provenance_and_the_report_shows_refusals(tmp_path: Path) -> None:
    folder = tmp_path / "proj" / "clips"
    manifest = _bvh_project(
        folder,
        (*DRAFT, *WALKS),
        "schema_version: 1\nname: loco\nskeleton: {units: m}\nclips:\n  - path: 'clips/*.bvh'\n"
        "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n"
        "  y: {feature: speed, min: -3, max: 6, divisions: 90}\nfixes: {too_close: merge}\n",
    )
    out = tmp_path / "out"
    doc = _run(manifest, out, "--format", "json")
    made = [s for s in doc["samples"] if s["generated"]]  # type: ignore[attr-defined]
    assert made
    for sample in made:
        for suffix in (".usda", ".bvh"):
            record = read_provenance(out / "clips" / f"{sample['name']}{suffix}")
            assert record is not None and record.tool == "blendspace-pipeline"
            assert (
                record.rule == sample["fix"] and record.sources and len(record.weights) == len(record.sources)
            )
    assert read_provenance(folder / "walk_13.bvh") is None  # authored: no record
    html = (out / "loco.report.html").read_text()
    assert 'id="refused"' in html and "never merges a key clip away" in html


def test_placeholders_beyond_the_simulation_budget_are_not_suggested(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from blendspace_pipeline.pipeline import placeholders
    from blendspace_pipeline.pipeline.analysis import analyse

    specs = (*DRAFT, GaitSpec("turn_in_place_right", turn_rate=-90.0, duration=2.0), *WALKS)
    manifest = _project(tmp_path, specs)
    checked = analyse(manifest)
    monkeypatch.setattr(placeholders, "BUDGET", 0)
    unchecked = analyse(manifest)
    acute = [d for d in unchecked.diagnostics if d.rule == "acute-triangle"]
    assert len(acute) == 6 and not any(d.placeholders for d in acute)  # unchecked: not suggested
    assert all("not checked by simulation" in (d.hint or "") for d in acute)
    # Checked, four of the six slivers have no single-clip cure and lose their marker.
    assert sum(not d.placeholders for d in checked.diagnostics if d.rule == "acute-triangle") == 4
