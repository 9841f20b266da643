"""The fix loop: check → bake new clips → re-measure, re-place, re-triangulate → check again.

Rules only describe fixes (`Diagnostic.fix` and `fix_data`); this module applies them, kind by
kind in a fixed order (too-close, then straighten, then mirror, then axis clips) because each
kind changes the triangulation the next one looks at. Every generated clip is real animation
made by `clip_ops` from the source clips and measured like any other clip, so it lands where its
features put it, not where the fix wished it to be. Sources are never modified or deleted: new
clips live in memory until the build writes them under ``clips/`` in its output.

The loop is monotone: each fix is tried on its own, the space analysed again, and the fix kept
only if the findings improve in this order (`score`): fewer errors; else as many errors and fewer
warnings; else as many of both and a larger covered share of the axis rectangle. A fix that
would drop an authored key clip (`key_clips`: on a main axis, or a corner of the convex hull) is
never kept, whatever the counts. A fix not kept is an info finding `fix-rejected` saying why.

The loop is bounded (`MAX_ROUNDS`, `MAX_ATTEMPTS`; a fix is tried again only after another was
kept) and deterministic (fixes are tried in sorted order, names are derived from the sources), and
it is idempotent: a clip of an earlier build fed back as a source is recognised by the provenance
in its file (`readers.provenance`), never by where it sits, and a set that already holds it
triggers no fix.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from blendspace_pipeline.diagnostics import Diagnostic
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.manifest.models import ClipEntry, MirrorTokens, SkeletonSettings
from blendspace_pipeline.motion.clip import Clip
from blendspace_pipeline.motion.clip_ops import IncompatibleClips, blend_clips, mirror_clip, straighten_clip
from blendspace_pipeline.motion.clip_ops.blend import measured_part
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import Measurement, measure, part_options, trim
from blendspace_pipeline.pipeline.analysis import finish_analysis
from blendspace_pipeline.pipeline.measure_stage import as_made, clip_settings, entry_settings
from blendspace_pipeline.pipeline.placeholders import converge_placeholders
from blendspace_pipeline.readers import read_clips
from blendspace_pipeline.readers.provenance import Provenance, read_provenance
from blendspace_pipeline.space.geometry import normalise
from blendspace_pipeline.space.hull import convex_hull, hull_coverage
from blendspace_pipeline.space.model import BlendSpace, MeasuredClip, Sample, assemble

MAX_ROUNDS = 6
# Fix kinds in the order they are applied: the set is made right (merged, straightened) before it
# is completed (mirrored, axis clips), so a mirror is of a clip the space keeps (mirrors first made
# `mid_a_mirror` of a take the merge then took out, beside the merged clip).
ORDER = ("too-close", "straighten", "mirror", "axis-clip")
# At most this many fixes are tried in one build (each costs a re-analysis of the space).
MAX_ATTEMPTS = 64


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
    weights: tuple[float, ...] = ()  # one per source (a mirror or straighten: (1.0,))
    made_with: RigSettings | None = None  # how the fix read its sources: how it is measured


@dataclass
class FixState:
    """What the loop has done so far (the build writes `generated`)."""

    generated: dict[str, GeneratedClip] = field(default_factory=dict)
    removed: dict[str, str] = field(default_factory=dict)  # sample name -> why
    # fix-skipped and fix-rejected findings, by the finding whose fix they are about (the last
    # word on a fix tried again)
    verdicts: dict[tuple[object, ...], Diagnostic] = field(default_factory=dict)


def apply_fixes(
    space: BlendSpace, jobs: int = 1, while_converging: Callable[[BlendSpace], None] | None = None
) -> tuple[BlendSpace, FixState]:
    """Apply the manifest's `fixes:` one at a time, keeping each only if it improves the space.
    ``while_converging``: as `converge_placeholders`' ``meanwhile``, for the last space."""
    state = FixState()
    fixer = _Fixer(space, state)
    # Each fix is tried once per state of the space: one not kept is tried again once another
    # fix was kept after it (the mirror of a walking turn, no better before the turn in place
    # was mirrored, is better after; the next build, with that mirror fed back as a source, made
    # it, and a build was not idempotent).
    # Fixes never tried go first; a retry spends the same budget (`MAX_ATTEMPTS`).
    tried: dict[tuple[object, ...], int] = {}  # fix -> how many fixes had been kept after trying it
    kept_fixes = attempts = 0
    for _ in range(MAX_ROUNDS):
        progress = False
        for kind in ORDER:
            if not fixer.enabled(kind):
                continue
            while attempts < MAX_ATTEMPTS:
                todo = fixer.todo(space, kind)
                diagnostic = next((d for d in todo if _attempt_key(kind, d) not in tried), None) or next(
                    (d for d in todo if tried[_attempt_key(kind, d)] < kept_fixes), None
                )
                if diagnostic is None:
                    break
                attempts += 1
                space, kept = fixer.attempt(space, kind, diagnostic)
                kept_fixes += kept
                tried[_attempt_key(kind, diagnostic)] = kept_fixes
                progress |= kept
        if not progress:
            break
    if attempts >= MAX_ATTEMPTS:
        fixer.out_of_attempts(space, set(tried))
    converge_placeholders(space, jobs=jobs, meanwhile=while_converging)
    # What was said of a fix whose finding a later fix cured is no longer so.
    present = {_about(d) for d in space.diagnostics}
    said = [verdict for about, verdict in state.verdicts.items() if about in present]
    space.diagnostics = sorted(space.diagnostics + said + _removals(space, fixer), key=Diagnostic.sort_key)
    return space, state


def _about(diagnostic: Diagnostic) -> tuple[object, ...]:
    """Which finding ``diagnostic`` is: its rule, clips and position (a fix's verdicts go by it)."""
    position = None if diagnostic.position is None else tuple(round(v, 6) for v in diagnostic.position)
    return (diagnostic.rule, tuple(sorted(diagnostic.clips)), position)


def _attempt_key(kind: str, diagnostic: Diagnostic) -> tuple[object, ...]:
    return (kind, *_about(diagnostic))


Score = tuple[int, int, float]


def score(space: BlendSpace) -> Score:
    """The order fixes must improve, smaller is better: errors, then warnings, then coverage.

    Coverage is the share of the axis rectangle inside the hull of the samples (negated, so
    that more is better). The fix loop's own info findings are not counted.
    """
    errors = sum(d.severity == "error" for d in space.diagnostics)
    warnings = sum(d.severity == "warning" for d in space.diagnostics)
    points = [(float(x), float(y)) for x, y in space.normalised_positions()]
    return errors, warnings, -round(hull_coverage(points), 6)


def key_clips(space: BlendSpace, made_earlier: Callable[[str], bool] = lambda _name: False) -> dict[str, str]:
    """Authored clips no fix may lose, with why: on a main axis, or a corner of the hull.

    "On a main axis" means the clip's measured (unsnapped) position lies within
    `thresholds.crossing_axis` (normalised units; the paper's τχ = 5) of the line speed = 0 or
    turning = 0: the band crossing-axis already treats as on the axis. A hull corner is a vertex
    of the convex hull of the authored samples (placed positions): dropping it shrinks the
    coverage. ``made_earlier(name)``: whether an earlier build made the sample (fed back as a
    source): such samples are neither keys nor part of that hull (the mirrors a build added had
    moved the hull, a corner stopped being one, and the next build merged it away). Asked only of
    the hull's corners and the clips on an axis: it reads the clip's file.
    """
    tau = space.manifest.model.thresholds.crossing_axis
    lines = []
    for index, axis in enumerate(space.axes):
        if axis.minimum <= 0.0 <= axis.maximum:
            lines.append((index, (0.0 - axis.minimum) / (axis.maximum - axis.minimum) * 100.0))
    found: dict[str, str] = {}
    points = [(float(x), float(y)) for x, y in space.normalised_positions()]
    authored = [not (s.generated or s.clip.extra.get("generated")) for s in space.samples]
    while True:  # the hull of the authored samples, without those an earlier build made
        corners = set(convex_hull([p for p, mine in zip(points, authored, strict=True) if mine]))
        made = [
            i
            for i, p in enumerate(points)
            if authored[i] and p in corners and made_earlier(space.samples[i].name)
        ]
        if not made:
            break
        for i in made:
            authored[i] = False
    for sample, placed, mine in zip(space.samples, points, authored, strict=True):
        if not mine:
            continue
        measured = _normalise(space, sample.measured)
        for index, line in lines:
            if abs(measured[index] - line) <= tau:
                if not made_earlier(sample.name):
                    found[sample.name] = f"on the {space.axes[index].feature} = 0 axis"
                break
        else:
            if placed in corners:
                found[sample.name] = "a corner of the covered area"
    return found


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
        self.sources = {s.name: s.clip for s in space.samples}
        self.clips: dict[str, Clip] = {}
        self._provenance: dict[str, Provenance | None] = {}
        # Key clips of the authored set: a clip of an earlier build (it says so in its file) is
        # not authored, and may go when the fix that made it is made again.
        self.keys = key_clips(space, lambda name: self.provenance(name) is not None)

    # -- which fixes are on ---------------------------------------------------------------------
    def enabled(self, kind: str) -> bool:
        fixes = self.model.fixes
        return {
            "mirror": fixes.mirror,
            "axis-clip": fixes.axis_clips,
            "too-close": fixes.too_close != "report",
            "straighten": fixes.straighten,
        }[kind]

    def todo(self, space: BlendSpace, kind: str) -> list[Diagnostic]:
        """The findings of ``space`` that fix ``kind`` acts on, in a fixed order."""
        return sorted(
            (d for d in space.diagnostics if self._kind_of(d) == kind), key=lambda d: (d.clips, d.message)
        )

    @staticmethod
    def _kind_of(diagnostic: Diagnostic) -> str | None:
        if diagnostic.fix == "too-close":
            return "too-close"
        if diagnostic.rule == "misalignment" and diagnostic.clips and "expects" not in diagnostic.message:
            return "straighten"
        return diagnostic.fix if diagnostic.fix in ("mirror", "axis-clip") else None

    # -- applying -------------------------------------------------------------------------------
    def attempt(self, space: BlendSpace, kind: str, diagnostic: Diagnostic) -> tuple[BlendSpace, bool]:
        """Try one fix; keep it (return the new space, True) only if the space gets better."""
        generated, removed = dict(self.state.generated), dict(self.state.removed)
        try:
            changed = bool(getattr(self, "_" + kind.replace("-", "_"))(space, diagnostic))
        except IncompatibleClips as why:
            self._skip(diagnostic, f"cannot {kind}: {why}")
            changed = False
        except _Refused as why:
            self._reject(diagnostic, kind, str(why))
            changed = False
        if not changed:
            self.state.generated, self.state.removed = generated, removed
            return space, False
        candidate = self.rebuild(space)
        why_not = self._worse(space, candidate)
        if why_not is None:
            self.state.verdicts.pop(_about(diagnostic), None)  # an earlier try's verdict no longer holds
            return candidate, True
        self.state.generated, self.state.removed = generated, removed
        self._reject(diagnostic, kind, why_not)
        return space, False

    def out_of_attempts(self, space: BlendSpace, tried: set[tuple[object, ...]]) -> None:
        """A `fix-skipped` on each finding a fix was not tried on: the build stopped at
        `MAX_ATTEMPTS` (the next build, with the clips made fed back, may make more)."""
        for kind in ORDER:
            if self.enabled(kind):
                for diagnostic in self.todo(space, kind):
                    if _attempt_key(kind, diagnostic) not in tried:
                        self._skip(
                            diagnostic,
                            f"not tried: the build tries at most {MAX_ATTEMPTS} fixes",
                            hint="build again with the clips made so far among the sources, or author them",
                        )

    def _worse(self, before: BlendSpace, after: BlendSpace) -> str | None:
        """Why ``after`` is not better than ``before`` (see `score`), or None when it is."""
        present = {s.name for s in after.samples}
        # A key clip straightened stays at its key position, as its straight version (made now,
        # or by an earlier build and fed back as a source).
        replaced = {
            g.sources[0]
            for g in self.state.generated.values()
            if g.rule == "misalignment" and g.clip.name in present
        }
        for name in present:
            record = self.provenance(name) if name in self.sources else None
            if record is not None and record.rule == "misalignment":
                replaced.add(record.sources[0])
        lost = sorted(n for n in self.keys if n not in present and n not in replaced)
        if lost:
            return f"it would drop {self._why_key(lost)}"
        floating = self._floating(present)
        if floating is not None:
            return floating
        for name, generated in sorted(self.state.generated.items()):
            found = generated.measured.measurement if generated.measured is not None else None
            if name in present and found is not None and found.up_axis not in ("y", "z"):
                return f"{name}, the clip it makes, reads {found.up_axis.upper()} up: no clip file says so"
        old, new = score(before), score(after)
        if new < old:
            return None
        return (
            f"the space would not get better (at that step of the fixes): errors {old[0]} → {new[0]}, "
            f"warnings {old[1]} → {new[1]}, "
            f"coverage {-old[2] * 100:.1f}% → {-new[2] * 100:.1f}%"
        )

    def _floating(self, present: set[str]) -> str | None:
        """Why a clip made in the space plants no foot while each of its sources does (a blend of
        a standing idle and a run: feet in the air, the body tilted, its root motion right): an
        engine plays that blend there too, but a baked clip must be one to use. None otherwise."""
        for name, generated in sorted(self.state.generated.items()):
            measured = generated.measured
            if name not in present or measured is None or _plants(measured.measurement) is not False:
                continue
            sources = [self._measurement(n) for n in generated.sources]
            if all(m is not None and _plants(m) for m in sources):
                why = " (they share no gait: author a clip there)" if len(sources) > 1 else ""
                verb = "does" if len(sources) == 1 else "do"
                return f"{name}, the clip it makes, never plants a foot where {' and '.join(generated.sources)} {verb}{why}"
        return None

    def _measurement(self, name: str) -> Measurement | None:
        if name in self.state.generated:
            measured = self.state.generated[name].measured
            return measured.measurement if measured is not None else None
        return self.sources[name].measurement

    def _mirror(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        data = diagnostic.fix_data or {}
        source = str(data["source"])
        pairs = self._pairs(source)
        if pairs == {}:  # tokens set, and no joint pair carries them: never a silent guess instead
            tokens = entry_settings(self.model.skeleton, self._entry(source)).mirror
            shown = (
                f"{{left: {tokens.left}, right: {tokens.right}}}"
                if isinstance(tokens, MirrorTokens)
                else tokens
            )
            self._skip(
                diagnostic,
                f"skeleton.mirror {shown} pairs no joints of {source}: no joint holds one token "
                "where another joint holds the other",
                hint="set skeleton.mirror to the rig's side tokens (e.g. {left: Left, right: Right}, "
                "{left: _l, right: _r}), or remove it to pair the joints by their names and shape",
            )
            return False
        name = self._unique(mirrored_name(source))
        settings = self._read_as(source)
        clip = mirror_clip(self._clip(source), settings=settings, name=name, pairs=pairs)
        return self._add(clip, "missing-opposite", (source,), f"mirror of {source}", (1.0,), settings)

    def _axis_clip(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        data = diagnostic.fix_data or {}
        axis_index = 0 if data["axis"] == "x" else 1
        point = tuple(float(v) for v in data["point"])  # type: ignore[attr-defined]
        near = self._nearest_within_too_close(space, point)
        if near is not None:
            sample, distance = near
            self._skip(
                diagnostic,
                f"{sample.name} sits {distance:.3g} (normalised) from the crossing point "
                f"({point[0]:.3g}, {point[1]:.3g}), within too_close ({self.model.thresholds.too_close:g}): "
                "a clip there would be too close to it",
                hint=f"author a clip at the crossing point yourself and accept its too-close warning, "
                f"move {sample.name}, or lower thresholds.too_close below {distance:.3g}",
            )
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
        settings = self._shared_settings((a.name, b.name))  # before either file is read
        clip = blend_clips([self._clip(a.name), self._clip(b.name)], weights, name=name, settings=settings)
        note = f"{weights[0]:.3f} x {a.name} + {weights[1]:.3f} x {b.name}"
        return self._add(clip, "crossing-axis", (a.name, b.name), note, weights, settings)

    def _too_close(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        data = diagnostic.fix_data or {}
        members = [n for n in diagnostic.clips if n not in self.state.removed]
        if len(members) < 2:
            return False
        earlier = self._earlier_fix(members, "too-close")
        if earlier is not None:  # a fixed build's merged clip fed back as a source: keep it
            done, sources = earlier
            for name in sources:
                self.state.removed[name] = f"too-close: {done} already merges it"
            return True
        # Key clips stay whatever the fix: the others are merged or dropped around them.
        kept = [n for n in members if n in self.keys]
        loose = [n for n in members if n not in self.keys]
        if self.model.fixes.too_close == "keep-representative":
            keep = kept[0] if kept else str(data.get("keep", members[0]))
            if keep not in members:
                keep = members[0]
            dropped = [n for n in members if n != keep and n not in kept]
            if not dropped:
                raise _Refused(f"{self._why_key(kept)}; too-close never drops a key clip")
            for name in dropped:
                self.state.removed[name] = f"too-close: {keep} kept as the representative"
            return True
        if len(loose) < 2:
            raise _Refused(f"{self._why_key(kept)}; too-close never merges a key clip away")
        name = self._unique(_safe("merged_" + "_".join(sorted(loose))))
        settings = self._shared_settings(sorted(loose))  # before any file is read
        clips = [self._clip(n) for n in sorted(loose)]
        weights = [1.0 / len(clips)] * len(clips)
        clip = blend_clips(clips, weights, name=name, settings=settings)
        for member in loose:
            self.state.removed[member] = f"too-close: merged into {name}"
        return self._add(
            clip, "too-close", tuple(sorted(loose)), "equal-weight merge", tuple(weights), settings
        )

    def _straighten(self, space: BlendSpace, diagnostic: Diagnostic) -> bool:
        source = diagnostic.clips[0]
        # Generated clips are straightened too (a merge of a turning and a straight walk turns a
        # little); otherwise feeding them back as sources would straighten them a build later.
        if source in self.state.removed:
            return False
        earlier = self._earlier_fix([s.name for s in space.samples], "misalignment", source)
        if earlier is not None:  # a fixed build's straightened clip fed back as a source
            self.state.removed[source] = f"misalignment: {earlier[0]} already is its straight version"
            return True
        name = self._unique(_safe(f"{source}_straight"))
        settings = self._read_as(source)
        clip = straighten_clip(self._clip(source), settings=settings, name=name)
        self.state.removed[source] = f"misalignment: replaced by {name}"
        return self._add(clip, "misalignment", (source,), "turn removed", (1.0,), settings)

    # -- helpers --------------------------------------------------------------------------------
    def _clip(self, name: str) -> Clip:
        """The animation of sample ``name``: a generated clip, or the source read, cut to its
        `range:` and to the frames it was measured on (held keys and a rest frame left out: a
        mirrored clip had kept a 4 s hold that the measurement, and every other fix, left out)."""
        if name in self.state.generated:
            return self.state.generated[name].clip
        if name not in self.clips:
            measured = self.sources[name]
            animation = str(measured.extra.get("animation", name))
            clips = read_clips(measured.source, project=self.original.manifest.directory)
            clip = next((c for c in clips if c.name == animation), clips[0])
            # Its own `tpose:` too, but for a clip an earlier build made (fed back as a source).
            read_as = as_made(
                clip_settings(self.model.skeleton, measured.entry), self.provenance(name) is not None
            )
            self.clips[name] = measured_part(
                trim(clip, measured.time_range), read_as, **part_options(measured.entry.range)
            )
        return self.clips[name]

    def _entry(self, name: str) -> ClipEntry:
        """The manifest entry sample ``name`` came from (a generated clip: its first source's)."""
        while name in self.state.generated and name not in self.sources:
            name = self.state.generated[name].sources[0]
        return self.sources[name].entry

    def _settings(self, name: str) -> RigSettings:
        """How the fixes treat sample ``name``'s clip, once `_clip` has cut it to its measured
        frames: its entry's `skeleton:` keys over the top-level ones (with the top-level ones, the
        mirror of a Z-up take under `skeleton: {up: z}` had been measured Y-up), and `tpose: keep`:
        the clip starts on its first frame of motion (a `drop` cut a real frame off each clip made
        from it, and off each clip made)."""
        return replace(clip_settings(self.model.skeleton, self._entry(name)), tpose="keep")

    def _read_as(self, name: str) -> RigSettings:
        """`_settings` with the up axis and unit its measurement read (an `up: auto` that found
        Y reads as `up: y` does)."""
        settings = self._settings(name)
        found = self._measurement(name)
        if found is None:
            return settings
        # Only an up axis a manifest can state (a take read X or -Y up stays as its entry says).
        up = found.up_axis if found.up_axis in ("y", "z") else settings.up
        return replace(settings, up=up, units=float(found.meters_per_unit))

    def _shared_settings(self, names: Sequence[str]) -> RigSettings:
        """One way to read samples ``names``, blended into one clip: each key as the samples that
        state it state it (the others leave it `auto`), the up axis and unit as measured. Raises
        `IncompatibleClips` when two samples are read differently: the blend would be measured
        one way, and one of them misread."""
        found = {n: self._read_as(n) for n in names}
        shared: dict[str, object] = {}
        for key in (k.name for k in fields(RigSettings)):
            stated = [(n, getattr(found[n], key)) for n in names if getattr(found[n], key) != "auto"]
            for b, y in stated[1:]:
                a, x = stated[0]
                if _differ(x, y):
                    raise IncompatibleClips(
                        f"{a} and {b} are read with different `skeleton:` settings ({key}: {x} against "
                        f"{y}); a blend of them would be measured one way"
                    )
            shared[key] = stated[0][1] if stated else "auto"
        return RigSettings(**shared)  # type: ignore[arg-type]

    def _pairs(self, source: str) -> dict[str, str] | None:
        tokens = entry_settings(self.model.skeleton, self._entry(source)).mirror
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

    def _nearest_within_too_close(
        self, space: BlendSpace, point: Sequence[float]
    ) -> tuple[Sample, float] | None:
        """The sample nearest ``point`` and its (normalised) distance, when within `too_close`."""
        target = _normalise(space, point)
        found = min(
            ((s, _distance(_normalise(space, s.position), target)) for s in space.samples),
            key=lambda pair: pair[1],
            default=None,
        )
        return found if found is not None and found[1] < self.model.thresholds.too_close else None

    # Idempotence: building again with a fixed build's generated clips among the sources must add
    # nothing. Mirror and axis clips cure their own diagnostic; a merge or a straightened clip
    # does not (the originals are back beside it), so these two fixes first look for a sample
    # whose file says it is their result. Only the file's provenance counts: an authored clip
    # that happens to sit where a merge would land is an authored clip.
    def provenance(self, name: str) -> Provenance | None:
        """The provenance record in sample ``name``'s file (None: authored, or made in this build)."""
        if name not in self._provenance:
            origin = self.sources.get(name)
            self._provenance[name] = read_provenance(origin.source) if origin is not None else None
        return self._provenance[name]

    def _earlier_fix(
        self, candidates: Sequence[str], rule: str, source: str | None = None
    ) -> tuple[str, tuple[str, ...]] | None:
        """A sample among ``candidates`` that an earlier build's ``rule`` fix made from samples
        still in the space (from ``source`` alone, when given), with those sources."""
        present = {n for n in self.sources if n not in self.state.removed}
        for name in sorted(candidates):
            record = self.provenance(name)
            if record is None or record.rule != rule or name in self.state.removed:
                continue
            sources = tuple(n for n in record.sources if n in present and n != name)
            if source is not None:
                if record.sources == (source,):
                    return name, (source,)
            elif sources and all(n in candidates for n in sources):
                return name, sources
        return None

    def _unique(self, name: str) -> str:
        taken = set(self.sources) | set(self.state.generated)
        candidate, counter = name, 1
        while candidate in taken:
            counter += 1
            candidate = f"{name}_{counter}"
        return candidate

    def _add(
        self,
        clip: Clip,
        rule: str,
        sources: tuple[str, ...],
        note: str,
        weights: tuple[float, ...],
        made_with: RigSettings,
    ) -> bool:
        clip.notes.append(f"generated by the {rule} fix: {note}")
        first = sources[0]
        origin = self.sources.get(first)
        line, column = (
            (origin.line, origin.column)
            if origin is not None
            else (self.state.generated[first].line, self.state.generated[first].column)
        )
        self.state.generated[clip.name] = GeneratedClip(
            clip,
            rule,
            sources,
            note,
            line,
            column,
            weights=tuple(float(w) for w in weights),
            made_with=made_with,
        )
        return True

    def _skip(
        self, diagnostic: Diagnostic, why: str, hint: str = "author the clip at the placeholder instead"
    ) -> None:
        self._say(
            diagnostic,
            Diagnostic(
                rule="fix-skipped",
                code="BS903",
                severity="info",
                message=f"{diagnostic.rule} fix not applied: {why}",
                clips=diagnostic.clips,
                position=diagnostic.position,
                hint=hint,
                path=diagnostic.path,
                line=diagnostic.line,
                column=diagnostic.column,
            ),
        )

    def _say(self, diagnostic: Diagnostic, verdict: Diagnostic) -> None:
        """Keep ``verdict`` on ``diagnostic``'s fix, in place of what an earlier try said."""
        about = _about(diagnostic)
        self.state.verdicts.pop(about, None)
        self.state.verdicts[about] = verdict

    def _why_key(self, names: Sequence[str]) -> str:
        listed = ", ".join(f"{n} ({self.keys[n]})" for n in names)
        return f"{listed} {'is a key clip' if len(names) == 1 else 'are key clips'} of the authored set"

    def _reject(self, diagnostic: Diagnostic, kind: str, why: str) -> None:
        self._say(
            diagnostic,
            Diagnostic(
                rule="fix-rejected",
                code="BS907",
                severity="info",
                message=f"{kind} fix for {diagnostic.rule} not applied: {why}",
                clips=diagnostic.clips,
                position=diagnostic.position,
                hint="the build keeps a fix only if the space gets better; "
                "author a clip at the placeholder, or set the fix to `report`",
                path=diagnostic.path,
                line=diagnostic.line,
                column=diagnostic.column,
            ),
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
                # As the fix read its sources: auto-detected again, a merge made Y up read -Y up.
                measurement = measure(generated.clip, generated.made_with or self._settings(name))
            except InputError as error:  # a generated clip that cannot be measured is our bug
                raise RuntimeError(f"generated clip {name} cannot be measured: {error}") from error
            generated.measured = MeasuredClip(
                name,
                Path("clips") / f"{name}.usda",
                # Its sources' `skeleton:` keys (but `tpose`, see `_settings`): the maps play it with them.
                ClipEntry(path=f"clips/{name}.usda", skeleton=_made_from(self._entry(generated.sources[0]))),
                generated.line,
                generated.column,
                measurement,
                extra={"generated": True},
            )
        return generated.measured


class _Refused(Exception):
    """A fix that must not be made (it would lose a key clip): becomes a fix-rejected finding."""


def _plants(measurement: Measurement) -> bool | None:
    """Whether a clip plants a foot at all; None where no feet were found (nothing to say)."""
    contacts = measurement.contacts
    return None if contacts is None else any(spans for spans in contacts.values())


def _made_from(entry: ClipEntry) -> SkeletonSettings:
    """The `skeleton:` keys of a clip made from ``entry``'s clips: the same, with no rest frame."""
    return (entry.skeleton or SkeletonSettings()).model_copy(update={"tpose": "keep"})


def _differ(x: object, y: object) -> bool:
    """Two values of a rig setting that read a clip differently (units measured as floats agree
    within a millionth)."""
    if isinstance(x, float) and isinstance(y, float):
        return abs(x - y) > 1e-6 * max(abs(x), abs(y))
    return x != y


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
