"""A small harness for rule authors: build a blend space in a few lines and run one rule on it.

    from blendspace_pipeline.testing import space_from_positions, run_rule

    space = space_from_positions({"idle": (0, 0), "walk": (0, 1.4), "run_left": (90, 4.0)})
    findings = run_rule(MyRule, space)
    assert [f.clips for f in findings] == [("run_left",)]
    assert run_rule(MyRule, space, min_seconds=2.0) == []  # keyword arguments are MyRule's options

`space_from_specs` does the same from procedural clips (`procedural.GaitSpec`), measuring them
for real, so a rule sees exactly what a build would give it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace

import numpy as np

from blendspace_pipeline.api import Rule, SampleView, SpaceView
from blendspace_pipeline.checks.rule_engine import finding_problem, known_clip_names, rule_problem
from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.space.placement import Axis
from blendspace_pipeline.space.triangulate import triangulate

DEFAULT_AXES = (Axis("x", "turn_rate", -180.0, 180.0, 100), Axis("y", "speed", -3.0, 6.0, 90))
DEFAULT_THRESHOLDS = {"crossing_axis": 5.0, "too_close": 8.0, "acute_angle": 15.0, "misalignment": 3.0}


def _normalised(position: Sequence[float], axes: tuple[Axis, Axis]) -> tuple[float, float]:
    return (
        (position[0] - axes[0].minimum) / (axes[0].maximum - axes[0].minimum) * 100.0,
        (position[1] - axes[1].minimum) / (axes[1].maximum - axes[1].minimum) * 100.0,
    )


def space_from_positions(
    positions: Mapping[str, Sequence[float]],
    *,
    axes: tuple[Axis, Axis] = DEFAULT_AXES,
    thresholds: Mapping[str, float] | None = None,
    features: Mapping[str, Mapping[str, float]] | None = None,
    expect: Mapping[str, Mapping[str, float]] | None = None,
    snap: bool = True,
    triangles: Iterable[tuple[int, int, int]] | None = None,
) -> SpaceView:
    """A space with samples at ``positions`` (axis units), Delaunay-triangulated like a build."""
    samples = []
    for name, measured in positions.items():
        measured_xy = (float(measured[0]), float(measured[1]))
        position = (axes[0].snap(measured_xy[0]), axes[1].snap(measured_xy[1])) if snap else measured_xy
        sample_features = {axes[0].feature: measured_xy[0], axes[1].feature: measured_xy[1], "duration": 1.0}
        sample_features.update((features or {}).get(name, {}))
        samples.append(
            SampleView(
                name=name,
                source=f"{name}.bvh",
                position=position,
                measured=measured_xy,
                normalised=_normalised(position, axes),
                features=sample_features,
                expect=(expect or {}).get(name),
                frames=31,
                fps=30.0,
                in_place=abs(sample_features.get("speed", 1.0)) < 0.05
                and abs(sample_features.get("turn_rate", 10.0)) < 3.0,
            )
        )
    if triangles is None:
        points = np.array([s.normalised for s in samples], dtype=np.float64).reshape(-1, 2)
        triangles = triangulate(points).triangles
    return SpaceView(
        name="test",
        axes=axes,
        samples=tuple(samples),
        triangles=tuple(tuple(t) for t in triangles),  # type: ignore[misc]
        thresholds={**DEFAULT_THRESHOLDS, **(thresholds or {})},
    )


def space_from_specs(
    specs: Iterable[object], *, axes: tuple[Axis, Axis] = DEFAULT_AXES, **options: object
) -> SpaceView:
    """Like `space_from_positions`, from procedural clips measured for real."""
    from blendspace_pipeline.motion.measure import measure
    from blendspace_pipeline.motion.procedural import GaitSpec, generate

    positions: dict[str, tuple[float, float]] = {}
    features: dict[str, dict[str, float]] = {}
    gaits: dict[str, dict[str, object]] = {}
    for spec in specs:
        assert isinstance(spec, GaitSpec)
        measurement = measure(generate(spec), RigSettings())
        measured = measurement.features
        positions[spec.name] = (measured[axes[0].feature], measured[axes[1].feature])
        features[spec.name] = measured
        # The gait facts a build's view carries too (stride period, foot contacts, plant phases).
        gaits[spec.name] = {
            "gait_period": measurement.gait_period,
            "contacts": measurement.contacts,
            "plant_phases": measurement.plant_phases,
        }
    space = space_from_positions(positions, axes=axes, features=features, **options)  # type: ignore[arg-type]
    samples = tuple(replace(s, **gaits[s.name]) for s in space.samples)  # type: ignore[arg-type]
    return replace(space, samples=samples)


def run_rule(rule: type[Rule], space: SpaceView, /, **options: object) -> list[Diagnostic]:
    """Every finding of ``rule`` on ``space``, sorted like the build sorts them.

    Keyword arguments are the rule's typed options, validated by its `Options` model exactly as
    the manifest's `rules: {options: ...}` would be (a pydantic ValidationError if wrong). The rule
    and what it yields are checked as the engine checks them, so a rule that passes here does not
    become `plugin-error` or `rule-crashed` in a build: an AssertionError says why it would.
    """
    problem = rule_problem(rule)
    assert problem is None, f"the loader would refuse {rule.__name__}: it {problem}"
    if options and rule.Options is None:
        raise TypeError(f"{rule.slug} takes no options")
    chosen = rule.Options.model_validate(options) if rule.Options is not None else None
    known = known_clip_names(space)
    findings = []
    for item in rule(options=chosen).check(space):
        problem = finding_problem(item, rule, known)
        assert problem is None, f"the engine would report {rule.slug} as rule-crashed: {problem}"
        assert isinstance(item, Diagnostic)  # for the type checker; finding_problem checked it
        findings.append(item)
    return sorted(findings, key=Diagnostic.sort_key)
