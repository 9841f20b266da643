"""The analysed `BlendSpace` as the engine-neutral JSON document (spec.md's layout)."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from pathlib import Path

from blendspace_pipeline import __version__
from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.features import FEATURE_UNITS
from blendspace_pipeline.motion.contacts import FootContacts, sync_markers
from blendspace_pipeline.space.document import (
    AxisDoc,
    BlendSpaceDocument,
    BuildInfoDoc,
    ClipInfoDoc,
    DiagnosticDoc,
    LocationDoc,
    MarkerDoc,
    PlaceholderDoc,
    SampleDoc,
)
from blendspace_pipeline.space.layers_doc import (
    BetaLayerDoc,
    MaskDoc,
    StyleAxisDoc,
    StyleLayerDoc,
    StyleSampleDoc,
)
from blendspace_pipeline.space.model import BetaSpace, BlendSpace, Layer, MeasuredClip, Sample

DECIMALS = 6  # stable, diff-friendly numbers; far below any measurement's precision


def _r(value: float) -> float:
    return round(float(value), DECIMALS) + 0.0


def relative_path(path: Path, base: Path) -> str:
    """``path`` relative to ``base`` with forward slashes, or absolute when on another drive.

    A library's clips share a few folders: each folder is made relative once (`os.path.relpath`
    per clip was half of a 1,000-clip document's time) and the file name joined to it."""
    text, base_text, cwd = os.fspath(path), os.fspath(base), os.getcwd()
    head, name = os.path.split(text)
    folder = _relative_folder(head or ".", base_text, cwd) if name not in ("", ".", "..") else None
    if folder is None or folder[1]:
        # Not a plain file name, another drive, or a folder above ``base`` (the name may lead
        # back into ``base``'s own path: relpath normalises that, a join would not).
        whole = _relative_folder(text, base_text, cwd)
        return Path(path).as_posix() if whole is None else whole[0]
    return name if folder[0] == "." else f"{folder[0]}/{name}"


@functools.lru_cache(maxsize=4096)
def _relative_folder(folder: str, base: str, cwd: str) -> tuple[str, bool] | None:
    """``folder`` relative to ``base`` (both taken from ``cwd`` when relative), posix, and whether
    it only climbs (every part ``..``); None when there is no relative path (another drive)."""
    try:
        relative = Path(os.path.relpath(folder, base)).as_posix()
    except ValueError:
        return None
    return relative, set(relative.split("/")) == {".."}


def _sample_doc(sample: Sample, out_dir: Path, *, events: bool = True) -> SampleDoc:
    """``events=False``: without the foot contacts and sync markers (`maps_document`)."""
    m = sample.clip.measurement
    entry = sample.clip.entry
    return SampleDoc(
        name=sample.name,
        source=relative_path(sample.clip.source, out_dir),
        features={k: _r(v) for k, v in m.features.items()},
        position=[_r(sample.position[0]), _r(sample.position[1])],
        generated=sample.generated,
        fix=sample.fix,
        snapping_error=[_r(e) for e in sample.snapping_error],
        manual_position=[float(v) for v in entry.position] if entry.position is not None else None,
        clip=_clip_info(sample.clip),
        contacts=m.contacts if events else None,
        markers=_markers(m.contacts, m.features["duration"]) if events else None,
    )


class SampleDocsAhead:
    """Sample documents made ahead of `to_document`, by this process while the placeholder
    simulations run in forked ones (`converge_placeholders`' ``meanwhile``): a sample's document
    does not depend on the findings. `to_document` takes each one whose sample still reads the
    same (the same objects and values, the same output folder and working folder), and makes the
    others (a fix's generated clip gets its file name only when the outputs are written)."""

    def __init__(self, out_dir_of: Callable[[BlendSpace], Path]) -> None:
        self.out_dir_of = out_dir_of
        self.docs: dict[int, tuple[_SampleKey, SampleDoc]] = {}

    def prepare(self, space: BlendSpace) -> None:
        try:
            out_dir = self.out_dir_of(space)
            self.docs = {id(s): (_sample_key(s, out_dir), _sample_doc(s, out_dir)) for s in space.samples}
        except Exception:  # an optimisation only: `to_document` makes them, and reports what fails
            self.docs = {}

    def sample_doc(self, sample: Sample, out_dir: Path) -> SampleDoc:
        made = self.docs.pop(id(sample), None)
        if made is not None and _same_key(made[0], _sample_key(sample, out_dir)):
            return made[1]
        return _sample_doc(sample, out_dir)


# What `_sample_doc` reads: the objects themselves (compared by identity, and held, so that no new
# object takes a freed one's id) and the values (with the output and working folders).
_SampleKey = tuple[tuple[object, ...], tuple[object, ...]]


def _sample_key(sample: Sample, out_dir: Path) -> _SampleKey:
    clip = sample.clip
    objects = (sample, clip, clip.measurement, clip.entry)
    values = (clip.source, clip.time_range, sample.position, sample.measured, sample.generated, sample.fix)
    return objects, (*values, out_dir, os.getcwd())


def _same_key(made: _SampleKey, now: _SampleKey) -> bool:
    return all(a is b for a, b in zip(made[0], now[0], strict=True)) and made[1] == now[1]


def _used_range(clip: MeasuredClip) -> list[float] | None:
    """The seconds of the file the clip's numbers come from, when not all of it: the frames
    measured, not the range asked for (a Godot clip resampled at 30.4 fps used 0.263-0.987 s of
    `range: [0.25, 1.0]`; its duration and speeds are of those frames), and a take whose first
    frame, a rest pose, was left out starts at its second (contacts and markers count from there)."""
    used = clip.measurement.range_used
    span = used if used is not None else clip.time_range
    return None if span is None else [float(v) for v in span]


def _markers(contacts: dict[str, list[list[float]]] | None, duration: float) -> list[MarkerDoc] | None:
    """Foot-down events of the measured contacts, the same seconds as `contacts`."""
    if contacts is None:
        return None
    events = sync_markers(FootContacts.from_json(contacts, duration))
    return [MarkerDoc(name=name, time=_r(time)) for time, name in events]  # type: ignore[arg-type]


def _clip_info(clip: MeasuredClip) -> ClipInfoDoc:
    m = clip.measurement
    entry = clip.entry
    return ClipInfoDoc(
        duration=_r(m.features["duration"]),
        fps=_r(m.fps),
        frames=m.frames,
        meters_per_unit=_r(m.meters_per_unit),
        units_source=m.units_source,
        up_axis=m.up_axis,
        root=m.root,
        facing=m.facing,
        range=_used_range(clip),
        range_auto=entry.range == "auto",
        guesses=[f"{g.what} guessed as {g.value}: set `{g.override}`" for g in m.guesses],
        notes=list(m.notes),
        gait_period=_r(m.gait_period) if m.gait_period is not None else None,
        plant_phases=m.plant_phases,
    )


def layer_doc(layer: Layer, out_dir: Path) -> BetaLayerDoc | StyleLayerDoc:
    """A beta or style layer in the JSON's `layers` list (see `layers_doc`)."""
    if isinstance(layer, BetaSpace):
        sub = layer.space
        return BetaLayerDoc(
            name=layer.name,
            kind="beta",
            source=relative_path(layer.manifest, out_dir),
            samples=[_sample_doc(s, out_dir) for s in sub.samples],
            triangles=[list(t) for t in sub.triangles],
            diagnostics=[diagnostic_doc(d, out_dir) for d in sub.all_diagnostics()],
        )
    axis = layer.axis
    return StyleLayerDoc(
        name=layer.name,
        kind="style",
        axis=StyleAxisDoc(
            feature=axis.feature, min=axis.minimum, max=axis.maximum, unit=FEATURE_UNITS[axis.feature]
        ),
        samples=[
            StyleSampleDoc(
                name=clip.name,
                source=relative_path(clip.source, out_dir),
                position=[_r(value)],
                features={k: _r(v) for k, v in clip.measurement.features.items()},
                clip=_clip_info(clip),
            )
            for clip, value in zip(layer.clips, layer.positions, strict=True)
        ],
        mask=MaskDoc(joints=dict(layer.mask.joints), default=layer.mask.default) if layer.mask else None,
        diagnostics=[],
    )


def diagnostic_doc(diagnostic: Diagnostic, out_dir: Path | None = None) -> DiagnosticDoc:
    """``out_dir`` given: the location is relative to it, like every other path in the document,
    so a build's JSON and HTML do not depend on the working folder or how the manifest was typed."""
    location = None
    if diagnostic.path is not None:
        where = diagnostic.path if out_dir is None else relative_path(Path(diagnostic.path), out_dir)
        location = LocationDoc(path=where, line=diagnostic.line, column=diagnostic.column)
    return DiagnosticDoc(
        rule=diagnostic.rule,
        code=diagnostic.code,
        severity=diagnostic.severity,
        message=diagnostic.message,
        clips=list(diagnostic.clips),
        position=[_r(v) for v in diagnostic.position] if diagnostic.position is not None else None,
        fix=diagnostic.fix,
        hint=diagnostic.hint,
        location=location,
    )


def maps_document(space: BlendSpace, out_dir: Path) -> BlendSpaceDocument:
    """What the blend quality maps read of `to_document(space, out_dir)`: the axes, the triangles
    and the samples without their foot contacts and sync markers (the maps play the clips' own
    contacts), and none of the findings, placeholders, layers or build settings. The early maps
    child (`early_quality`) makes it in half of the whole document's time."""
    return BlendSpaceDocument(
        schema_version=1,
        name=space.name,
        axes=_axis_docs(space),
        samples=[_sample_doc(s, out_dir, events=False) for s in space.samples],
        triangles=[list(t) for t in space.triangles],
    )


def _axis_docs(space: BlendSpace) -> list[AxisDoc]:
    return [
        AxisDoc(
            name=a.name,  # type: ignore[arg-type]  # placement axes are named "x"/"y"
            feature=a.feature,
            min=a.minimum,
            max=a.maximum,
            divisions=a.divisions,
            unit=FEATURE_UNITS[a.feature],
        )
        for a in space.axes
    ]


def to_document(
    space: BlendSpace, out_dir: Path, prepared: SampleDocsAhead | None = None
) -> BlendSpaceDocument:
    """``prepared``: sample documents made ahead (`SampleDocsAhead`)."""
    model = space.manifest.model
    return BlendSpaceDocument(
        schema_version=1,
        name=space.name,
        axes=_axis_docs(space),
        samples=[
            prepared.sample_doc(s, out_dir) if prepared is not None else _sample_doc(s, out_dir)
            for s in space.samples
        ],
        triangles=[list(t) for t in space.triangles],
        diagnostics=[diagnostic_doc(d, out_dir) for d in space.diagnostics],
        placeholders=[
            PlaceholderDoc(
                position=[_r(v) for v in p.position],
                priority=p.priority,
                rule=p.rule,
                reason=p.reason,
                features={k: _r(v) for k, v in p.features.items()},
            )
            for p in space.placeholders
        ],
        layers=[layer_doc(layer, out_dir).model_dump(mode="json") for layer in space.layer_spaces],
        build=BuildInfoDoc(
            tool_version=__version__,
            manifest=relative_path(space.manifest.path, out_dir),
            thresholds=model.thresholds.model_dump(),
            settings={
                "skeleton": model.skeleton.model_dump(mode="json"),
                "rules": model.rules.model_dump(mode="json"),
                "fixes": model.fixes.model_dump(mode="json"),
            },
        ),
    )
