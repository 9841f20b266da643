"""The stable surface for rule authors: everything a rule module imports comes from here.

A rule is a class with a slug, a code, a default severity, a one-line summary and a docstring
(its user documentation). `check(space)` receives a read-only `SpaceView` and yields
`Diagnostic`s made with `self.report(...)`. Rules never change the space: a fix is data on the
diagnostic (`fix=` and `fix_data=`) that the engine applies, and placeholders say which clip
would cure the problem. Built-in rules (the top-level `rules/` folder) are written the same way.

    from blendspace_pipeline.api import Field, Rule, RuleOptions, SpaceView

    class NoTinyClips(Rule):
        \"\"\"Clips shorter than half a second rarely hold a full gait cycle.\"\"\"
        slug = "studio-short-clip"
        code = "ST001"
        severity = "warning"
        summary = "clip shorter than a minimum length"

        class Options(RuleOptions):
            min_seconds: float = Field(0.5, gt=0, description="Shortest acceptable clip, seconds.")

        def check(self, space: SpaceView):
            for sample in space.samples:
                if sample.features["duration"] < self.options.min_seconds:
                    yield self.report(f"{sample.name} lasts {sample.features['duration']:.2f} s",
                                      clips=[sample.name], position=sample.position)

A manifest sets options by slug or code: `rules: {options: {studio-short-clip: {min_seconds: 1}}}`.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import ClassVar, TypeVar

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field

from blendspace_pipeline.diagnostics import Diagnostic, Placeholder, Severity
from blendspace_pipeline.features import FEATURE_UNITS
from blendspace_pipeline.motion.notes import STILL_NOTE
from blendspace_pipeline.space.placement import Axis
from blendspace_pipeline.space.triangulate import triangle_edges

__all__ = [
    "Axis",
    "DetectionGuessView",
    "Diagnostic",
    "LayerView",
    "Placeholder",
    "Rule",
    "SampleView",
    "Severity",
    "SpaceView",
]

_V = TypeVar("_V")


def _frozen_array(values: object, dtype: type, shape: tuple[int, ...]) -> NDArray[np.float64]:
    """A read-only array: views are shared by every rule, like the mappings."""
    array: NDArray[np.float64] = np.array(values, dtype=dtype).reshape(shape)
    array.flags.writeable = False
    return array


def _read_only(mapping: Mapping[str, _V]) -> Mapping[str, _V]:
    """A read-only copy: one view is shared by every rule, and none may change what the next sees.

    The copy also cuts the view off from the caller's dict (the engine's measurements, a test's
    literal), so a later change there does not show through either.
    """
    return MappingProxyType(dict(mapping))


@dataclass(frozen=True)
class DetectionGuessView:
    """A decision about a clip that its data did not settle (up axis, units, root or facing):
    the value used, the evidence seen, and the manifest setting that replaces the guess.
    ``stated``: a value the file or the manifest states that the data contradicts (used, doubted)."""

    what: str
    value: str
    evidence: str
    override: str
    stated: bool = False


@dataclass(frozen=True)
class SampleView:
    """A placed clip as rules see it. Positions are in axis units; ``normalised`` in 0..100."""

    name: str
    source: str
    position: tuple[float, float]
    measured: tuple[float, float]
    normalised: tuple[float, float]
    features: Mapping[str, float]
    generated: bool = False
    fix: str | None = None
    expect: Mapping[str, float] | None = None
    frames: int = 0
    fps: float = 0.0
    meters_per_unit: float = 1.0
    units_source: str = ""
    up_axis: str = "y"
    in_place: bool = False
    units_guessed: bool = False
    joint_names: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    guesses: tuple[DetectionGuessView, ...] = ()
    # Same key: same joint names, hierarchy and rest offsets (one rig), so one up axis and unit.
    skeleton_key: str = ""
    # Seconds per stride, None without a gait (idle, turning on the spot).
    gait_period: float | None = None
    # Foot contacts: per foot ("left", "right"), (start, end) seconds of the used range.
    contacts: Mapping[str, tuple[tuple[float, float], ...]] | None = None
    # Stride phase (0..1) at which each foot plants, None without a gait or contacts.
    plant_phases: Mapping[str, float] | None = None
    # Stepping with no whole stride measured: turn and direction keep the pelvis sway.
    partial_stride: bool = False
    # Each joint's parent, an index into `joint_names` (-1: a root); () when unknown (a track set
    # without hierarchy, a view built without it).
    joint_parents: tuple[int, ...] = ()
    # Who says the up axis: "manifest", "file" (its own axis settings) or "detected" (the body).
    up_source: str = "detected"

    @property
    def holds_still(self) -> bool:
        """Every frame measured holds one pose (a still idle, a pose exported as an animation): no
        motion, so no frame rate or stride to disagree with another clip's."""
        return STILL_NOTE in self.notes

    def __post_init__(self) -> None:
        # Frozen dataclasses only stop attribute assignment; the mappings need freezing too.
        object.__setattr__(self, "features", _read_only(self.features))
        if self.contacts is not None:
            spans = {foot: tuple((float(a), float(b)) for a, b in v) for foot, v in self.contacts.items()}
            object.__setattr__(self, "contacts", _read_only(spans))
        if self.plant_phases is not None:
            object.__setattr__(self, "plant_phases", _read_only(self.plant_phases))
        if self.expect is not None:
            object.__setattr__(self, "expect", _read_only(self.expect))
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "joint_parents", tuple(self.joint_parents))
        object.__setattr__(self, "notes", tuple(self.notes))
        object.__setattr__(self, "guesses", tuple(self.guesses))


@dataclass(frozen=True)
class LayerView:
    """A beta or style layer of the space, read-only (see `blendspace_pipeline.pipeline.layers`).

    A beta layer has the two axes of its own manifest and its samples placed on them. A style
    layer has one axis (a main-space axis, normally speed); its samples' positions are
    ``(value, 0.0)``. ``mask`` is the style's per-joint weights (None: all joints).
    """

    name: str
    kind: str  # "beta" or "style"
    axes: tuple[Axis, ...]
    samples: tuple[SampleView, ...]
    mask: Mapping[str, float] | None = None
    mask_default: float = 1.0
    axes_match: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", tuple(self.samples))
        if self.mask is not None:
            object.__setattr__(self, "mask", _read_only(self.mask))


@dataclass(frozen=True)
class SpaceView:
    """The placed, triangulated blend space, read-only."""

    name: str
    axes: tuple[Axis, Axis]
    samples: tuple[SampleView, ...]
    triangles: tuple[tuple[int, int, int], ...]
    thresholds: Mapping[str, float]
    # Unused by the engine (a rule reads its own validated options as `self.options`); kept
    # because it is part of the published view.
    options: Mapping[str, Mapping[str, object]] = field(default_factory=dict)
    layers: tuple[LayerView, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", tuple(self.samples))
        object.__setattr__(self, "triangles", tuple(tuple(t) for t in self.triangles))
        object.__setattr__(self, "thresholds", _read_only(self.thresholds))
        object.__setattr__(self, "options", _read_only({k: _read_only(v) for k, v in self.options.items()}))
        object.__setattr__(self, "layers", tuple(self.layers))

    def sample(self, name: str) -> SampleView:
        for sample in self.samples:
            if sample.name == name:
                return sample
        raise KeyError(name)

    def to_normalised(self, position: Sequence[float]) -> tuple[float, float]:
        x_axis, y_axis = self.axes
        return (
            (position[0] - x_axis.minimum) / (x_axis.maximum - x_axis.minimum) * 100.0,
            (position[1] - y_axis.minimum) / (y_axis.maximum - y_axis.minimum) * 100.0,
        )

    def to_axis_units(self, normalised: Sequence[float]) -> tuple[float, float]:
        x_axis, y_axis = self.axes
        return (
            normalised[0] / 100.0 * (x_axis.maximum - x_axis.minimum) + x_axis.minimum,
            normalised[1] / 100.0 * (y_axis.maximum - y_axis.minimum) + y_axis.minimum,
        )

    def features_at(self, position: Sequence[float]) -> dict[str, float]:
        """The feature values a clip placed at ``position`` must have."""
        return {self.axes[0].feature: float(position[0]), self.axes[1].feature: float(position[1])}

    def edges(self) -> list[tuple[int, int]]:
        """Every triangle edge once, as sorted sample-index pairs."""
        return list(self._edges)

    @cached_property
    def _edges(self) -> tuple[tuple[int, int], ...]:
        # Computed once per view (several rules walk the edges), in the order `sorted` gives.
        return tuple(triangle_edges(self.triangles))

    # Vectorised views, for rules that must scale to thousands of samples: read-only numpy
    # arrays in sample order, computed once per view and shared by every rule.

    @cached_property
    def positions(self) -> NDArray[np.float64]:
        """(N, 2) placed positions, axis units."""
        return _frozen_array([s.position for s in self.samples], np.float64, (-1, 2))

    @cached_property
    def normalised_positions(self) -> NDArray[np.float64]:
        """(N, 2) placed positions, normalised (0..100 per axis)."""
        return _frozen_array([s.normalised for s in self.samples], np.float64, (-1, 2))

    @cached_property
    def measured_positions(self) -> NDArray[np.float64]:
        """(N, 2) measured (unsnapped) positions, axis units."""
        return _frozen_array([s.measured for s in self.samples], np.float64, (-1, 2))

    @cached_property
    def triangle_array(self) -> NDArray[np.int64]:
        """(T, 3) triangles as sample indices."""
        return _frozen_array(self.triangles, np.int64, (-1, 3))  # type: ignore[return-value]

    def feature_array(self, feature: str) -> NDArray[np.float64]:
        """(N,) a measured feature of every sample; NaN where a sample lacks it."""
        return _frozen_array([s.features.get(feature, np.nan) for s in self.samples], np.float64, (-1,))

    def close_pairs(self, radius: float) -> NDArray[np.int64]:
        """(P, 2) index pairs ``i < j`` of samples closer than ``radius`` in normalised units,
        sorted; found with a k-d tree (about n log n), not by testing all n^2 pairs."""
        points = self.normalised_positions
        if len(points) < 2 or radius <= 0.0:
            return np.zeros((0, 2), dtype=np.int64)
        from scipy.spatial import cKDTree  # local import: scipy loads only when a rule asks

        found = cKDTree(points).query_pairs(radius, output_type="ndarray")
        pairs: NDArray[np.int64] = np.asarray(found, dtype=np.int64).reshape(-1, 2)
        pairs.sort(axis=1)
        difference = points[pairs[:, 0]] - points[pairs[:, 1]]
        pairs = pairs[np.hypot(difference[:, 0], difference[:, 1]) < radius]  # strictly closer
        return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]

    def close_groups(self, radius: float) -> list[list[int]]:
        """Groups of two or more samples linked by chains of `close_pairs` (connected components),
        each as sorted sample indices, ordered by their first index."""
        pairs = self.close_pairs(radius)
        if not len(pairs):
            return []
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        count = len(self.samples)
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(count, count))
        _, labels = connected_components(graph, directed=False)
        sizes = np.bincount(labels)
        groups: dict[int, list[int]] = {}
        for index, label in enumerate(labels.tolist()):
            if sizes[label] > 1:
                groups.setdefault(label, []).append(index)
        return list(groups.values())


class RuleOptions(BaseModel):
    """Base of a rule's typed options: unknown keys are errors, values are read-only.

    Give every field a default and a description (``Field(1.0, description=...)``): the
    description is what `blendspace rules` prints.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)


class Rule:
    """Base class of every rule, built-in or studio-made."""

    slug: ClassVar[str]
    code: ClassVar[str]
    severity: ClassVar[Severity]
    summary: ClassVar[str]
    fixable: ClassVar[bool] = False
    # Typed options: a pydantic model (every field with a default and a description) that the
    # manifest fills from `rules: {options: {<slug>: {...}}}`; the engine validates it, with line
    # numbers, before the rule runs. None: the rule takes no options.
    Options: ClassVar[type[RuleOptions] | None] = None

    def __init__(self, severity: Severity | None = None, options: RuleOptions | None = None) -> None:
        # The engine makes a new instance for every run, so options and severity never leak
        # from one blend space (or one manifest's `rules:`) into the next.
        self.effective_severity: Severity = severity or self.severity
        if options is None and self.Options is not None:
            options = self.Options()
        if options is not None and (self.Options is None or not isinstance(options, self.Options)):
            expected = self.Options.__name__ if self.Options is not None else "no options"
            raise TypeError(f"{self.slug} takes {expected}, not {type(options).__name__}")
        self.options = options

    def check(self, space: SpaceView) -> Iterable[Diagnostic]:
        raise NotImplementedError

    def report(
        self,
        message: str,
        *,
        clips: Iterable[str] = (),
        position: Sequence[float] | None = None,
        hint: str | None = None,
        fix: str | None = None,
        fix_data: dict[str, object] | None = None,
        placeholders: Iterable[Placeholder] = (),
    ) -> Diagnostic:
        return Diagnostic(
            rule=self.slug,
            code=self.code,
            severity=self.effective_severity,
            message=message,
            # One name given as a string is that clip, not its letters ("clips not in the space:
            # _, a, d, f, k" for `clips="walk_fwd"`).
            clips=(clips,) if isinstance(clips, str) else tuple(clips),
            position=(float(position[0]), float(position[1])) if position is not None else None,
            fix=fix,
            hint=hint,
            placeholders=tuple(placeholders),
            fix_data=fix_data,
        )

    @classmethod
    def documentation(cls) -> str:
        return (cls.__doc__ or cls.summary).strip()


def placeholder(
    space: SpaceView, position: Sequence[float], priority: str, rule: str, reason: str
) -> Placeholder:
    """A placeholder at ``position`` (axis units) carrying the features a new clip must have."""
    point = (float(position[0]), float(position[1]))
    return Placeholder(
        position=point,
        priority="necessary" if priority == "necessary" else "suggested",
        rule=rule,
        reason=reason,
        features=space.features_at(point),
    )


def iter_rule_classes(namespace: Mapping[str, object]) -> Iterator[type[Rule]]:
    """Rule subclasses defined in a module namespace (what the loader collects)."""
    for value in namespace.values():
        if (
            isinstance(value, type)
            and issubclass(value, Rule)
            and value is not Rule
            and hasattr(value, "slug")
        ):
            yield value


__all__ += ["FEATURE_UNITS", "Field", "RuleOptions", "iter_rule_classes", "placeholder"]
