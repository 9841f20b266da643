"""Good and bad cases for every built-in rule, exact findings, via the rule-author harness."""

from __future__ import annotations

import pytest
from blendspace_pipeline.rules.acute_triangle import AcuteTriangle
from blendspace_pipeline.rules.axis_zero_off_grid import AxisZeroOffGrid
from blendspace_pipeline.rules.crossing_axis import CrossingAxis
from blendspace_pipeline.rules.degenerate_space import DegenerateSpace, DuplicatePosition
from blendspace_pipeline.rules.in_place_clip import InPlaceClip
from blendspace_pipeline.rules.inconsistent_set import InconsistentFps, InconsistentSkeleton
from blendspace_pipeline.rules.misalignment import Misalignment
from blendspace_pipeline.rules.missing_opposite import MissingOpposite
from blendspace_pipeline.rules.outside_axis_range import OutsideAxisRange
from blendspace_pipeline.rules.too_close import TooClose
from blendspace_pipeline.rules.uncovered_area import UncoveredArea, covered_fraction

from blendspace_pipeline.api import SpaceView
from blendspace_pipeline.motion.procedural import GaitSpec
from blendspace_pipeline.space.placement import Axis
from blendspace_pipeline.testing import run_rule, space_from_positions, space_from_specs

KEY_SET = {  # idle, turn in place +-90, forward and backward at turn 0, turning walks
    "idle": (0, 0),
    "walk": (0, 1.4),
    "walk_left": (60, 1.4),
    "walk_right": (-60, 1.4),
    "tip_left": (90, 0),
    "tip_right": (-90, 0),
    "back": (0, -1.2),
}


def test_crossing_axis_bad_case_exact() -> None:
    space = space_from_specs(
        [
            GaitSpec("idle", duration=1.0),
            GaitSpec("walk_left", speed=1.4, turn_rate=60.0, duration=1.0),
            GaitSpec("walk_right", speed=1.4, turn_rate=-60.0, duration=1.0),
        ]
    )
    findings = run_rule(CrossingAxis, space)
    crossings = [f for f in findings if f.clips]
    assert [f.clips for f in crossings] == [("walk_left", "walk_right")]
    assert crossings[0].position == pytest.approx((0.0, 1.4))
    assert crossings[0].fix == "axis-clip"
    assert crossings[0].placeholders[0].priority == "necessary"
    keys = sorted(p.position for f in findings if not f.clips for p in f.placeholders)
    # Turn in place at the largest authored turn rate (60, on its grid point 61.2), not at half
    # the axis range (90).
    assert keys == [pytest.approx(k, abs=1e-6) for k in [(-61.2, 0.0), (0.0, 1.4), (61.2, 0.0)]]


def test_crossing_axis_good_case_is_silent() -> None:
    assert run_rule(CrossingAxis, space_from_positions(KEY_SET)) == []


def test_crossing_axis_ignores_edges_near_the_axis() -> None:
    # Both ends 3 normalised units from x = 0 (10.8 deg/s): within the 5-unit threshold.
    space = space_from_positions({"idle": (0, 0), "a": (10.8, 1.4), "b": (-10.8, 1.4)})
    assert run_rule(CrossingAxis, space) == []
    wide = space_from_positions(
        {"idle": (0, 0), "a": (10.8, 1.4), "b": (-10.8, 1.4)}, thresholds={"crossing_axis": 2}
    )
    assert len([f for f in run_rule(CrossingAxis, wide) if f.clips]) == 1


def test_acute_triangle() -> None:
    sliver = space_from_positions({"a": (-90, 0), "b": (90, 0), "c": (0, 0.5)})
    findings = run_rule(AcuteTriangle, sliver)
    assert len(findings) == 1
    assert set(findings[0].clips) == {"a", "b", "c"}
    assert "angle" in findings[0].message and findings[0].placeholders[0].priority == "suggested"
    assert run_rule(AcuteTriangle, space_from_positions({"a": (-90, 0), "b": (90, 0), "c": (0, 6)})) == []


def test_misalignment_near_axis_and_expect() -> None:
    space = space_from_positions(
        {"idle": (0, 0), "run": (5.0, 4.0), "walk_left": (60, 1.4)},
        expect={"walk_left": {"turn_rate": 45.0}},
    )
    findings = run_rule(Misalignment, space)
    assert [f.clips for f in findings] == [("run",), ("walk_left",)]
    assert findings[0].placeholders[0].position == (0.0, 4.0)
    assert "expects 45" in findings[1].message
    assert findings[1].placeholders[0].position == (45.0, 1.4)
    # Exactly on the axis, or far from it: silent.
    assert (
        run_rule(Misalignment, space_from_positions({"idle": (0, 0), "run": (0, 4), "wide": (60, 4)})) == []
    )


def test_misalignment_uses_measured_offsets() -> None:
    # 1 deg/s snaps to 0 on a 3.6 deg/s grid, but the clip still turns: reported on its measured
    # offset (the old rule compared the snapped one and was silent).
    findings = run_rule(Misalignment, space_from_positions({"idle": (0, 0), "run": (1.0, 4.0), "x": (90, 2)}))
    assert [f.clips for f in findings] == [("run",)]
    assert "+1 deg/s" in findings[0].message
    # A -5 deg/s drift (1.39 normalised) is reported; the old `>=` on the snapped offset missed it.
    drift = run_rule(Misalignment, space_from_positions({"idle": (0, 0), "walk": (-5.0, 1.4), "x": (90, 2)}))
    assert [f.clips for f in drift] == [("walk",)] and "-5 deg/s" in drift[0].message
    assert drift[0].placeholders[0].position == (0.0, 1.4)
    # The edge is inclusive: exactly tau (3 normalised = 10.8 deg/s) is reported, just beyond is not.
    edge = {"idle": (0, 0), "x": (90, 2)}
    assert len(run_rule(Misalignment, space_from_positions({**edge, "w": (10.8, 1.4)}))) == 1
    assert run_rule(Misalignment, space_from_positions({**edge, "w": (10.9, 1.4)})) == []
    # Measurement noise (below 0.01 normalised = 0.036 deg/s) is not a turn.
    assert run_rule(Misalignment, space_from_positions({**edge, "w": (0.03, 1.4)})) == []


def test_too_close_clusters() -> None:
    space = space_from_positions(
        {"a": (0, 1.4), "b": (7.2, 1.5), "c": (14.4, 1.6), "far": (90, 4), "idle": (0, 0)}
    )
    findings = run_rule(TooClose, space)
    assert len(findings) == 1
    assert set(findings[0].clips) == {"a", "b", "c"}  # chained: a-b and b-c are each closer than 8
    assert findings[0].fix_data is not None and findings[0].fix_data["keep"] == "b"
    assert run_rule(TooClose, space_from_positions(KEY_SET)) == []


def test_uncovered_area_reports_percentage() -> None:
    full = {"a": (-180, -3), "b": (180, -3), "c": (180, 6), "d": (-180, 6)}
    assert run_rule(UncoveredArea, space_from_positions(full)) == []
    half = {"a": (-180, -3), "b": (180, -3), "c": (180, 6)}
    findings = run_rule(UncoveredArea, space_from_positions(half))
    assert "50.0%" in findings[0].message
    # Only what a body can do: turning in place as fast as the set does (180), and at 6 m/s no
    # more than 7 m/s^2 / 6 m/s = 66.8 deg/s; never the bare corner (-180, 6).
    marks = [p.position for p in findings[0].placeholders]
    assert marks == [pytest.approx(m, abs=0.05) for m in [(-180.0, 0.0), (-66.85, 6.0), (66.85, 6.0)]]
    assert "narrow" not in findings[0].message
    assert covered_fraction([(0, 0), (100, 0), (100, 100)]) == pytest.approx(0.5)


def test_uncovered_area_says_to_narrow_axes_wider_than_a_body_can_do() -> None:
    walks = {
        "idle": (0, 0),
        "walk": (0, 1.4),
        "left": (45, 1.4),
        "right": (-45, 1.4),
        "tip_l": (90, 0),
        "tip_r": (-90, 0),
        "back": (0, -1.0),
    }
    [finding] = run_rule(UncoveredArea, space_from_positions(walks))
    assert "narrow turn_rate to [-90, 90], speed to [-1, 1.4]" in finding.message
    for mark in finding.placeholders:  # never at the rectangle's corners (+-180, 6) or (+-180, -3)
        assert -90 <= mark.position[0] <= 90 and -1.0 <= mark.position[1] <= 1.4


def test_clip_level_rules() -> None:
    space = space_from_positions({"idle": (0, 0), "fast": (0, 7.5), "walk": (30, 1.4)})
    assert [f.clips for f in run_rule(InPlaceClip, space)] == [("idle",)]
    out = run_rule(OutsideAxisRange, space)
    assert [f.clips for f in out] == [("fast",)] and out[0].severity == "error"
    assert run_rule(InconsistentFps, space) == []


def test_inconsistent_fps_leaves_still_poses_out() -> None:
    """A still idle read at 24 fps among 30 fps takes (its two keys tell no rate) is no mixed
    export; a walk at 24 fps is."""
    from dataclasses import replace

    from blendspace_pipeline.motion.notes import STILL_NOTE

    space = space_from_positions({"idle": (0, 0), "walk": (0, 1.4), "run": (0, 3.5), "turn": (30, 1.4)})
    idle = replace(space.samples[0], fps=24.0, notes=(STILL_NOTE,))
    assert idle.holds_still and not space.samples[1].holds_still
    assert run_rule(InconsistentFps, replace(space, samples=(idle, *space.samples[1:]))) == []
    walk = replace(space.samples[1], fps=24.0)
    found = run_rule(InconsistentFps, replace(space, samples=(idle, walk, *space.samples[2:])))
    assert [f.clips for f in found] == [("walk",)]


def _on_skeletons(changes: dict[str, str | None]) -> SpaceView:
    """KEY_SET's positions, each clip with the joints of a procedural walk changed as ``changes``
    says (`hostile.SKELETON_CHANGES`; None: the walk's own skeleton)."""
    from dataclasses import replace

    from blendspace_pipeline.motion.hostile import on_other_skeleton
    from blendspace_pipeline.motion.procedural import generate

    walk = generate(GaitSpec("walk", speed=1.4, duration=0.5))
    space = space_from_positions(KEY_SET)
    samples = []
    for sample in space.samples:
        change = changes.get(sample.name)
        skeleton = (on_other_skeleton(walk, change) if change else walk).skeleton
        samples.append(replace(sample, joint_names=skeleton.names, joint_parents=skeleton.parents))
    return replace(space, samples=tuple(samples))


@pytest.mark.parametrize(
    "change, says",
    [
        ("namespaced", "missing ["),
        ("extra_joint", "extra ['prop_r']"),
        ("missing_leaf", "joints vs"),
        ("reparented", "in another hierarchy: "),
        ("reordered", "hierarchy in another order from joint 2, "),
    ],
)
def test_inconsistent_skeleton_names_each_kind_of_difference(change: str, says: str) -> None:
    """Names, hierarchy and order: a joint under another parent, or the same joints in another
    order, cannot be blended either (only names were compared)."""
    findings = run_rule(InconsistentSkeleton, _on_skeletons({"walk_left": change}))
    assert [f.clips for f in findings] == [("walk_left",)]
    assert says in findings[0].message, findings[0].message
    assert run_rule(InconsistentSkeleton, _on_skeletons({})) == []


def test_inconsistent_skeleton_says_where_a_reparented_joint_hangs() -> None:
    from blendspace_pipeline.motion.hostile import on_other_skeleton
    from blendspace_pipeline.motion.procedural import generate

    walk = generate(GaitSpec("walk", speed=1.4, duration=0.5)).skeleton
    moved = on_other_skeleton(generate(GaitSpec("walk", speed=1.4, duration=0.5)), "reparented").skeleton
    joint = next(i for i in range(len(walk.names)) if walk.parents[i] != moved.parents[i])
    message = run_rule(InconsistentSkeleton, _on_skeletons({"back": "reparented"}))[0].message
    expected = (
        f"{walk.names[joint]} under {walk.names[moved.parents[joint]]}, "
        f"not {walk.names[walk.parents[joint]]} as in the set"
    )
    assert expected in message, message


def test_inconsistent_skeleton_names_a_renamed_root() -> None:
    """Blender's FBX export names the armature node after the armature object, and a BVH it
    imported after the file: each clip then has its own root name ("missing ['back'], extra
    ['walk']" said nothing of why)."""
    from dataclasses import replace

    space = _on_skeletons({})
    renamed = [
        replace(s, joint_names=("walk_left", *s.joint_names[1:])) if s.name == "walk_left" else s
        for s in space.samples
    ]
    findings = run_rule(InconsistentSkeleton, replace(space, samples=tuple(renamed)))
    assert [f.clips for f in findings] == [("walk_left",)]
    assert "its root joint is named 'walk_left', the set's 'Hips'" in findings[0].message


def test_a_clip_without_hierarchy_is_compared_by_its_joint_names() -> None:
    """A Godot track set has no hierarchy: its joints are not "all roots" (every joint was
    reported as under no parent), and it does not switch the hierarchy check off for the rest."""
    from dataclasses import replace

    space = _on_skeletons({"walk_right": "reparented"})
    samples = tuple(replace(s, joint_parents=()) if s.name == "walk_left" else s for s in space.samples)
    findings = run_rule(InconsistentSkeleton, replace(space, samples=samples))
    assert [f.clips for f in findings] == [("walk_right",)]


def test_inconsistent_skeleton_without_the_hierarchy_compares_names() -> None:
    """A view built without parents (a studio's own test space) is not all reported."""
    from dataclasses import replace

    space = _on_skeletons({"walk_left": "reordered"})
    bare = replace(space, samples=tuple(replace(s, joint_parents=()) for s in space.samples))
    assert [f.clips for f in run_rule(InconsistentSkeleton, bare)] == [("walk_left",)]  # the order differs
    space = _on_skeletons({"walk_left": "reparented"})
    bare = replace(space, samples=tuple(replace(s, joint_parents=()) for s in space.samples))
    assert run_rule(InconsistentSkeleton, bare) == []


def test_degenerate_and_duplicates() -> None:
    line = space_from_positions({"a": (0, 0), "b": (0, 1), "c": (0, 2)})
    assert len(run_rule(DegenerateSpace, line)) == 1
    dup = space_from_positions({"a": (0, 1.4), "b": (0.5, 1.41), "c": (90, 0), "d": (-90, 0)})
    assert [f.clips for f in run_rule(DuplicatePosition, dup)] == [("a", "b")]


def test_axis_zero_off_grid() -> None:
    odd = (Axis("x", "turn_rate", -180, 180, 100), Axis("y", "speed", -3, 6, 10))
    findings = run_rule(AxisZeroOffGrid, space_from_positions({"a": (0, 0)}, axes=odd))
    assert len(findings) == 1 and "axis y" in findings[0].message


def test_missing_opposite_reports_each_lone_side_with_a_mirror_fix() -> None:
    space = space_from_positions({**KEY_SET, "run_left": (90, 4.0), "walk": (0, 1.4)})
    findings = run_rule(MissingOpposite, space)
    assert [(d.clips, d.position, d.fix) for d in findings] == [(("run_left",), (-90.0, 4.0), "mirror")]
    assert findings[0].fix_data == {"source": "run_left", "position": [-90.0, 4.0]}
    assert findings[0].placeholders[0].priority == "suggested"


def test_missing_opposite_accepts_near_counterparts_and_on_axis_clips() -> None:
    # A counterpart 5.4 deg/s (1.5 normalised) away is close enough; clips on the axis are their own mirror.
    space = space_from_positions({**KEY_SET, "run_left": (90, 4.0), "run_right": (-95.4, 4.0), "run": (0, 4)})
    assert run_rule(MissingOpposite, space) == []


def test_missing_opposite_needs_a_mirror_odd_axis() -> None:
    axes = (Axis("x", "forward_speed", -3, 6, 90), Axis("y", "speed", -3, 6, 90))
    space = space_from_positions({"idle": (0, 0), "walk": (1.4, 1.4), "run": (4, 4)}, axes=axes)
    assert run_rule(MissingOpposite, space) == []
