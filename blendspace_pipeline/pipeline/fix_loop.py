"""The fix loop: check → bake new clips → re-measure, re-place, re-triangulate → check again.

Rules only describe fixes (`Diagnostic.fix` and `fix_data`); this module applies them, one kind
per round in a fixed order (mirror, then axis clips, then too-close, then straighten) because
each kind changes the triangulation the next one looks at. Every generated clip is real
animation made by `clip_ops` from the source clips and measured like any other clip, so it lands
where its features put it, not where the fix wished it to be. Sources are never modified: new
clips live in memory until the build writes them under ``clips/`` in its output.

The loop is bounded (`MAX_ROUNDS`) and deterministic (fixes are applied in sorted order, names are
derived from the sources), and it is idempotent: a set that already holds the clips a fix would
make triggers no fix.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.manifest.models import ClipEntry, MirrorTokens
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.clip_ops import IncompatibleClips, blend_clips, mirror_clip, straighten_clip
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import measure, trim
from blendspace_pipeline.pipeline.analysis import finish_analysis
from blendspace_pipeline.pipeline.measure_stage import rig_settings
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.space.geometry import normalise
from blendspace_pipeline.space.model import BlendSpace, MeasuredClip, Sample, assemble

MAX_ROUNDS = 6
# Fix kinds in the order they are applied; one kind per round.
ORDER = ("mirror", "axis-clip", "too-close", "straighten")


@dataclass
class GeneratedClip:
    """A clip a fix made: the animation, and what made it."""

    clip: Clip
    rule: str
    sources: tuple[str, ...]
    note: str
    line: int  # manifest entry of the first source, where its diagnostics point
    column: int
    measured: MeasuredClip | None = None


@dataclass
class FixState:
    """What the loop has done so far (the build writes `generated`)."""

    generated: dict[str, GeneratedClip] = field(default_factory=dict)
    removed: dict[str, str] = field(default_factory=dict)  # sample name -> why
    skipped: list[Diagnostic] = field(default_factory=list)


def apply_fixes(space: BlendSpace) -> tuple[BlendSpace, FixState]:
    """Apply the manifest's `fixes:` until nothing fixable is left (or `MAX_ROUNDS`)."""
    state = FixState()
    fixer = _Fixer(space, state)
    for _ in range(MAX_ROUNDS):
        kind = next((k for k in ORDER if fixer.wanted(space, k)), None)
        if kind is None:
            break
        changed = fixer.apply(space, kind)
        if not changed:
            fixer.exhausted.add(kind)
            continue
        space = fixer.rebuild(space)
    space.diagnostics = sorted(
        space.diagnostics + state.skipped + _removals(space, fixer), key=Diagnostic.sort_key
    )
    return space, state


def _removals(space: BlendSpace, fixer: _Fixer) -> list[Diagnostic]:
    """An info line per sample a fix took out of the space, at its manifest entry."""
    found = []
    for name, why in sorted(fixer.state.removed.items()):
        origin = fixer.sources.get(name)
        generated = fixer.state.generated.get(name)
        line = origin.line if origin else generated.line if generated else None
        found.append(
            Diagnostic(
                rule="fix-removed",
                code="BS904",
                severity="info",
                message=f"{name} is left out of the blend space ({why})",
                clips=(name,),
                hint="set the fix to `report` in `fixes:` to keep every clip",
                path=str(space.manifest.path),
                line=line,
                column=origin.column if origin else None,
            )
        )
    return found


class _Fixer:
    def __init__(self, space: BlendSpace, state: FixState) -> None:
        self.original = space
        self.state = state
        self.model = space.manifest.model
        self.settings: RigSettings = rig_settings(self.model.skeleton)
        self.sources = {s.name: s.clip for s in space.samples}
        self.clips: dict[str, Clip] = {}
        self.exhausted: set[str] = set()

    # -- which fixes are on ---------------------------------------------------------------------
    def enabled(self, kind: str) -> bool:
        fixes = self.model.fixes
        return {
            "mirror": fixes.mirror,
            "axis-clip": fixes.axis_clips,
            "too-close": fixes.too_close != "report",
            "straighten": fixes.straighten,
        }[kind]

    def wanted(self, space: BlendSpace, kind: str) -> bool:
        return (
            kind not in self.exhausted
            and self.enabled(kind)
            and any(self._kind_of(d) == kind for d in space.diagnostics)
        )

    @staticmethod
    def _kind_of(diagnostic: Diagnostic) -> str | None:
        if diagnostic.fix == "too-close":
            return "too-close"
        if diagnostic.rule == "misalignment" and diagnostic.clips and "expects" not in diagnostic.message:
            return "straighten"
        return diagnostic.fix if diagnostic.fix in ("mirror", "axis-clip") else None

    # -- applying -------------------------------------------------------------------------------
    def apply(self, space: BlendSpace, kind: str) -> bool:
        todo = sorted(
            (d for d in space.diagnostics if self._kind_of(d) == kind), key=lambda d: (d.clips, d.message)
        )
        changed = False
        for diagnostic in todo:
            try:
                changed |= getattr(self, "_" + kind.replace("-", "_"))(space, diagnostic)
            except IncompatibleClips as why:
                self._skip(diagnostic, f"cannot {kind}: {why}")
        return changed

    def _mirror(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        data = diagnostic.fix_data or {}
        source = str(data["source"])
        name = self._unique(mirrored_name(source))
        clip = mirror_clip(self._clip(source), settings=self.settings, name=name, pairs=self._pairs(source))
        return self._add(clip, "missing-opposite", (source,), f"mirror of {source}")

    def _axis_clip(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        data = diagnostic.fix_data or {}
        axis_index = 0 if data["axis"] == "x" else 1
        point = tuple(float(v) for v in data["point"])  # type: ignore[attr-defined]
        if self._occupied(space, point):
            self._skip(diagnostic, "a sample already sits within too_close of the crossing point")
            return False
        pair = _bracketing_axis_clips(space, axis_index, point)
        if pair is None:
            self._skip(
                diagnostic,
                f"no clips on the {space.axes[axis_index].feature} = 0 axis on both sides of "
                f"({point[0]:.3g}, {point[1]:.3g}) to interpolate",
            )
            return False
        (a, da), (b, db) = pair
        weights = (db / (da + db), da / (da + db))  # the nearer clip weighs more; they sum to 1
        label = f"{space.axes[1 - axis_index].feature}_{point[1 - axis_index]:g}".replace("-", "m")
        name = self._unique(_safe(f"axis_{label}"))
        clip = blend_clips(
            [self._clip(a.name), self._clip(b.name)], weights, name=name, settings=self.settings
        )
        note = f"{weights[0]:.3f} x {a.name} + {weights[1]:.3f} x {b.name}"
        return self._add(clip, "crossing-axis", (a.name, b.name), note)

    def _too_close(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        data = diagnostic.fix_data or {}
        members = [n for n in diagnostic.clips if n not in self.state.removed]
        if len(members) < 2:
            return False
        if self.model.fixes.too_close == "keep-representative":
            keep = str(data["keep"])
            for name in members:
                if name != keep:
                    self.state.removed[name] = f"too-close: {keep} kept as the representative"
            return True
        done = self._earlier_merge(space, members)
        if done is not None:  # a fixed build's merged clip fed back as a source: keep it
            for name in members:
                if name != done:
                    self.state.removed[name] = f"too-close: {done} already merges it"
            return True
        name = self._unique(_safe("merged_" + "_".join(sorted(members))))
        clips = [self._clip(n) for n in sorted(members)]
        clip = blend_clips(clips, [1.0 / len(clips)] * len(clips), name=name, settings=self.settings)
        for member in members:
            self.state.removed[member] = f"too-close: merged into {name}"
        return self._add(clip, "too-close", tuple(sorted(members)), "equal-weight merge")

    def _straighten(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        source = diagnostic.clips[0]
        # Generated clips are straightened too (a merge of a turning and a straight walk turns a
        # little); otherwise feeding them back as sources would straighten them a build later.
        if source in self.state.removed:
            return False
        on_axis = self._straight_twin(space, diagnostic)
        if on_axis is not None:  # a fixed build's straightened clip fed back as a source
            self.state.removed[source] = f"misalignment: {on_axis} already sits on the axis in its place"
            return True
        name = self._unique(_safe(f"{source}_straight"))
        clip = straighten_clip(self._clip(source), settings=self.settings, name=name)
        self.state.removed[source] = f"misalignment: replaced by {name}"
        return self._add(clip, "misalignment", (source,), "turn removed")

    # -- helpers --------------------------------------------------------------------------------
    def _clip(self, name: str) -> Clip:
        """The animation of sample ``name``: a generated clip, or the source read and trimmed."""
        if name in self.state.generated:
            return self.state.generated[name].clip
        if name not in self.clips:
            measured = self.sources[name]
            animation = str(measured.extra.get("animation", name))
            clips = read_clips(measured.source)
            clip = next((c for c in clips if c.name == animation), clips[0])
            self.clips[name] = trim(clip, measured.time_range)
        return self.clips[name]

    def _pairs(self, source: str) -> dict[str, str] | None:
        tokens = self.model.skeleton.mirror
        if not isinstance(tokens, MirrorTokens):
            return None
        names = self._clip(source).skeleton.names
        pairs = {}
        for joint in names:
            if tokens.left in joint:
                other = joint.replace(tokens.left, tokens.right)
                if other in names:
                    pairs[joint] = other
                    pairs[other] = joint
        return pairs

    def _occupied(self, space: BlendSpace, point: Sequence[float]) -> bool:
        """Whether a sample already sits within `too_close` of ``point`` (normalised)."""
        tau = self.model.thresholds.too_close
        target = _normalise(space, point)
        return any(_distance(_normalise(space, s.position), target) < tau for s in space.samples)

    # Idempotence: building again with a fixed build's generated clips among the sources must add
    # nothing. Mirror and axis clips cure their own diagnostic; a merge or a straightened clip
    # does not (the originals are back beside it), so these two fixes first look for a sample
    # that already is their result: one that sits, within `SAME_PLACE`, where the fix would put
    # its clip. Files do not say they were generated (BVH cannot), so place is the evidence.
    SAME_PLACE = 1.5  # normalised units: snapping (half a cell) plus a blend's small error

    def _earlier_merge(self, space: BlendSpace, members: list[str]) -> str | None:
        """A member that sits at the centre of the others: the merge of an earlier build."""
        if len(members) < 3:
            return None
        at = {s.name: _normalise(space, s.measured) for s in space.samples}
        for name in sorted(members):
            others = [at[m] for m in members if m != name]
            centre = (sum(p[0] for p in others) / len(others), sum(p[1] for p in others) / len(others))
            if _distance(at[name], centre) < self.SAME_PLACE:
                return name
        return None

    def _straight_twin(self, space: BlendSpace, diagnostic: Diagnostic) -> str | None:
        """Another sample on the axis where straightening ``diagnostic``'s clip would put it."""
        source = diagnostic.clips[0]
        axis = 0 if (diagnostic.fix_data or {}).get("axis", "x") == "x" else 1
        by_name = {s.name: s for s in space.samples}
        if source not in by_name:
            return None
        target = list(by_name[source].measured)
        target[axis] = 0.0
        for sample in space.samples:
            if sample.name == source or sample.name in self.state.removed or sample.position[axis] != 0.0:
                continue
            if _distance(_normalise(space, sample.measured), _normalise(space, target)) < self.SAME_PLACE:
                return sample.name
        return None

    def _unique(self, name: str) -> str:
        taken = set(self.sources) | set(self.state.generated)
        candidate, counter = name, 1
        while candidate in taken:
            counter += 1
            candidate = f"{name}_{counter}"
        return candidate

    def _add(self, clip: Clip, rule: str, sources: tuple[str, ...], note: str) -> bool:
        clip.notes.append(f"generated by the {rule} fix: {note}")
        first = sources[0]
        origin = self.sources.get(first)
        line, column = (
            (origin.line, origin.column)
            if origin is not None
            else (self.state.generated[first].line, self.state.generated[first].column)
        )
        self.state.generated[clip.name] = GeneratedClip(clip, rule, sources, note, line, column)
        return True

    def _skip(self, diagnostic: Diagnostic, why: str) -> None:
        self.state.skipped.append(
            Diagnostic(
                rule="fix-skipped",
                code="BS903",
                severity="info",
                message=f"{diagnostic.rule} fix not applied: {why}",
                clips=diagnostic.clips,
                position=diagnostic.position,
                hint="author the clip at the placeholder instead",
                path=diagnostic.path,
                line=diagnostic.line,
                column=diagnostic.column,
            )
        )

    # -- rebuilding -----------------------------------------------------------------------------
    def rebuild(self, space: BlendSpace) -> BlendSpace:
        clips = [c for c in self.sources.values() if c.name not in self.state.removed]
        for generated in self.state.generated.values():
            if generated.clip.name in self.state.removed:
                continue
            clips.append(self._measured(generated))
        rebuilt = assemble(space.manifest, clips)
        by_name = {s.name: s for s in rebuilt.samples}
        for name, generated in self.state.generated.items():
            if name in by_name:
                _mark(by_name[name], generated.rule)
        rebuilt.layer_spaces = space.layer_spaces
        rebuilt.rules = space.rules
        finish_analysis(rebuilt)
        return rebuilt

    def _measured(self, generated: GeneratedClip) -> MeasuredClip:
        if generated.measured is None:
            name = generated.clip.name
            try:
                measurement = measure(generated.clip, self.settings)
            except InputError as error:  # a generated clip that cannot be measured is our bug
                raise RuntimeError(f"generated clip {name} cannot be measured: {error}") from error
            generated.measured = MeasuredClip(
                name,
                Path("clips") / f"{name}.usda",
                ClipEntry(path=f"clips/{name}.usda"),
                generated.line,
                generated.column,
                measurement,
                extra={"generated": True},
            )
        return generated.measured


def _normalise(space: BlendSpace, point: Sequence[float]) -> tuple[float, float]:
    """``point`` in axis units -> the 0..100 normalised space the thresholds are measured in."""
    x, y = normalise(np.asarray(point, dtype=np.float64), space.axis_ranges())
    return float(x), float(y)


def _distance(a: Sequence[float], b: Sequence[float]) -> float:
    return float(((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5)


def _mark(sample: Sample, rule: str) -> None:
    sample.generated = True
    sample.fix = rule


def _bracketing_axis_clips(
    space: BlendSpace, axis_index: int, point: Sequence[float]
) -> tuple[tuple[Sample, float], tuple[Sample, float]] | None:
    """The nearest clip on each side of ``point`` among the clips lying on the crossed main axis.

    ``axis_index`` is the coordinate that is zero on the axis (0: x = 0, 1: y = 0); "on the axis"
    means within the misalignment threshold of it, in normalised units.
    """
    tau = space.manifest.model.thresholds.misalignment
    normalised = space.normalised_positions()
    zero = space.axes[axis_index]
    line = (0.0 - zero.minimum) / (zero.maximum - zero.minimum) * 100
    along = 1 - axis_index
    other = space.axes[along]
    target = (point[along] - other.minimum) / (other.maximum - other.minimum) * 100
    below: tuple[Sample, float] | None = None
    above: tuple[Sample, float] | None = None
    for sample, n in zip(space.samples, normalised, strict=True):
        if abs(n[axis_index] - line) > tau:
            continue
        offset = float(n[along] - target)
        if offset < 0 and (below is None or -offset < below[1]):
            below = (sample, -offset)
        elif offset > 0 and (above is None or offset < above[1]):
            above = (sample, offset)
    if below is None or above is None:
        return None
    return below, above


_SIDES = (("left", "right"), ("Left", "Right"), ("LEFT", "RIGHT"), ("_l", "_r"), ("_L", "_R"))


def mirrored_name(name: str) -> str:
    """``walk_turn_left`` -> ``walk_turn_right``; names without a side get ``_mirror``."""
    for left, right in _SIDES:
        swap = {left: right, right: left}
        # Short tokens (_l/_r) only count at the end of a word: "walk_loop" has no side.
        end = r"(?=$|[_\-.\d])" if len(left) <= 2 else ""
        pattern = re.compile(rf"(?:{re.escape(left)}|{re.escape(right)}){end}")
        if pattern.search(name):
            return pattern.sub(lambda m, swap=swap: swap[m.group(0)], name)  # type: ignore[misc]
    return f"{name}_mirror"


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.\-]", "_", name)
