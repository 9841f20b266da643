"""Placeholders that converge: a suggested clip position is kept only if a clip there helps.

A rule proposes where a new clip would cure its finding (the paper's green markers). Before the
build passes that on, it tries it: a virtual sample at the position, the space placed and
triangulated again, every rule run again. The position stands when its finding is gone and no
other error or warning appeared; otherwise the nearest candidate around it that does (`_candidates`)
takes its place; when none does, the finding says that no single clip helps and carries no
suggestion. The search is capped (`MAX_SIMULATIONS`, `BUDGET`); an unchecked position is never
suggested. Necessary placeholders (the method's key clips, crossing points, straight versions)
are the method's own answers and are never moved.

For `uncovered-area` (one finding, several marks) "gone" means the covered share grows. A
`too-close` marker is where the cluster's merge would go: its simulation takes the members out.

A virtual sample has no animation: what rules say about its animation alone (a missing mirrored
opposite, an in-place clip, its cadence) is not counted against it; where it sits is.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from blendspace_pipeline.checks.rule_engine import run_rules
from blendspace_pipeline.diagnostics import Diagnostic, Placeholder
from blendspace_pipeline.manifest.models import ClipEntry
from blendspace_pipeline.pipeline.forked import results_of
from blendspace_pipeline.space.hull import hull_coverage
from blendspace_pipeline.space.model import BlendSpace, MeasuredClip, Sample, assemble

VIRTUAL = "(placeholder)"
# Findings about a clip's own animation: not counted when only the virtual sample has them.
_CLIP_LEVEL_OK = frozenset({"misalignment", "outside-axis-range"})
MAX_TRIES = 12  # simulations per placeholder (each is a placement, triangulation and rule run)
# A simulation costs about 20 ms on a 13-clip set and grows with the samples, so the whole search
# is capped: at most `MAX_SIMULATIONS` per space, and at most `BUDGET` sample-simulations
# (simulations x samples: a 100-clip set gets 20, a 1,000-clip set 2). Placeholders beyond the
# cap are not suggested (unchecked, they might add a finding), and their finding says so.
# Counts, not times, so that builds stay byte-identical (numbers: benchmarks/bench_placeholders.py).
MAX_SIMULATIONS = 96
BUDGET = 2_000
SEVERE = ("error", "warning")
# Simulations run side by side (`--jobs`) from this many samples: a fork costs 5-10 ms, a
# simulation ~2 ms on the 13-clip sample project and ~80 ms at 1,000 clips.
PARALLEL_FROM = 300

Key = tuple[object, ...]


def converge_placeholders(
    space: BlendSpace, jobs: int = 1, meanwhile: Callable[[BlendSpace], None] | None = None
) -> None:
    """Check every suggested placeholder of ``space`` by simulation; move or drop the bad ones.

    ``jobs`` > 1: when a simulation is needed, the ones the search would make next if this one
    failed are made at the same time in forked processes (`_Trials`): the search then finds them
    done when it gets there. It still makes the same trials in the same order, so the outcome is
    the serial one.
    ``meanwhile``: work on ``space`` that does not depend on its findings (it must not raise),
    done by this process while the first simulations run in forked ones (`build` makes the
    samples' documents there); not called when nothing is simulated in parallel."""
    if len(space.samples) < 3 or not any(
        p.priority == "suggested" for d in space.diagnostics for p in d.placeholders
    ):
        return
    before = _keys(space.diagnostics)
    coverage = _coverage(space)
    budget = [min(MAX_SIMULATIONS, BUDGET // max(len(space.samples), 1))]
    trials = _Trials(space, jobs if len(space.samples) >= PARALLEL_FROM else 1, meanwhile)

    changed: list[Diagnostic] = []
    for diagnostic in space.diagnostics:
        if not any(p.priority == "suggested" for p in diagnostic.placeholders):
            changed.append(diagnostic)
            continue
        own = _key(diagnostic)
        marks: list[Placeholder] = []
        lost = 0
        moved: list[tuple[float, float]] = []
        unchecked = False
        for mark in diagnostic.placeholders:
            if mark.priority != "suggested":
                marks.append(mark)
                continue
            found = None
            if budget[0] <= 0:
                trials.next_mark()
                unchecked = True  # never suggested unchecked: it might add a finding
                continue
            index = trials.next_mark()
            for tried, point in enumerate(trials.candidates(index)):
                if budget[0] <= 0:
                    break
                budget[0] -= 1
                after, covered = trials.simulate(index, tried, budget[0])
                cured = covered > coverage + 1e-9 if diagnostic.rule == "uncovered-area" else own not in after
                if cured and not (after - before):
                    found = point
                    break
            if found is None and budget[0] <= 0:
                unchecked = True  # ran out of budget before an answer
            elif found is None:
                lost += 1
            elif found == mark.position:
                marks.append(mark)
            else:
                features = {space.axes[0].feature: float(found[0]), space.axes[1].feature: float(found[1])}
                marks.append(replace(mark, position=found, features=features))
                moved.append(found)
        note = ""
        if lost and not any(m.priority == "suggested" for m in marks):
            note = "no single added clip removes this finding without adding another"
        elif moved:
            # Several marks can move to the same position (their placeholders are merged below):
            # each position once, in the order found.
            at = ", ".join(dict.fromkeys(f"({p[0]:.3g}, {p[1]:.3g})" for p in moved))
            # Say what the simulation tested: for uncovered-area that coverage grew (`cured`).
            helps = "covers more of the space" if diagnostic.rule == "uncovered-area" else "removes it"
            note = f"tried by simulation, a clip at {at} {helps} without adding a finding"
        if unchecked:
            extra = "its placeholder was not checked by simulation (budget spent), so none is suggested"
            note = f"{note}; {extra}" if note else extra
        if note:
            diagnostic = diagnostic.evolve(hint=f"{diagnostic.hint}; {note}" if diagnostic.hint else note)
        changed.append(diagnostic.evolve(placeholders=tuple(_unique(marks))))
    space.diagnostics = changed
    space.placeholders = _unique(p for d in changed for p in d.placeholders)


class _Trials:
    """The simulations of one search, remembered by position, and the suggested placeholders in
    the order the search visits them (`next_mark` counts them off)."""

    def __init__(
        self, space: BlendSpace, jobs: int, meanwhile: Callable[[BlendSpace], None] | None = None
    ) -> None:
        self.space, self.jobs = space, jobs
        self.meanwhile = meanwhile if jobs > 1 else None  # done once, beside the first batch
        # A too-close marker is where the cluster's merge would go: it replaces the members.
        self.marks = [
            (d, mark, d.clips if d.rule == "too-close" else ())
            for d in space.diagnostics
            for mark in d.placeholders
            if mark.priority == "suggested"
        ]
        self.visited = 0
        self.done: dict[Key, tuple[set[Key], float]] = {}
        self._candidates: dict[int, list[tuple[float, float]]] = {}
        # What every mark's candidates are tested against, made once per search (a 1,000-clip
        # search visited 85 marks, and rebuilding these per mark was half of its time).
        self.by_name = {s.name: s for s in space.samples}
        self._staying: dict[tuple[str, ...], NDArray[np.float64]] = {}

    def next_mark(self) -> int:
        self.visited += 1
        return self.visited - 1

    def candidates(self, at: int) -> list[tuple[float, float]]:
        """The positions tried for mark ``at``, in order (at most `MAX_TRIES`)."""
        if at not in self._candidates:
            diagnostic, mark, without = self.marks[at]
            if without not in self._staying:
                self._staying[without] = _staying(self.space, without)
            found = _candidates(
                self.space, diagnostic, mark, without, staying=self._staying[without], by_name=self.by_name
            )
            self._candidates[at] = found[:MAX_TRIES]
        return self._candidates[at]

    def simulate(self, at: int, tried: int, budget_left: int) -> tuple[set[Key], float]:
        """The errors and warnings with a clip at candidate ``tried`` of mark ``at``, and the
        coverage.

        A new simulation takes along, up to ``jobs`` in all and no more than the budget left
        could use, the trials that follow it when it fails: the mark's next candidates, then the
        next marks'. Most candidates fail (with no budget cap, the marks of a 1,000-clip
        procedural library took 4 trials each, the sample project's 1 or all 12), so that is
        the search's likeliest path."""
        without = self.marks[at][2]
        key = _trial_key(self.candidates(at)[tried], without)
        if key not in self.done:
            batch: list[tuple[tuple[float, float], tuple[str, ...]]] = []
            mark, index = at, tried
            while len(batch) < min(self.jobs, 1 + budget_left) and mark < len(self.marks):
                if index >= len(self.candidates(mark)):
                    mark, index = mark + 1, 0
                    continue
                trial = (self.candidates(mark)[index], self.marks[mark][2])
                if not batch or (_trial_key(*trial) not in self.done and trial not in batch):
                    batch.append(trial)
                index += 1
            tasks: list[Callable[[], tuple[set[Key], float] | None]] = [
                functools.partial(_trial, self.space, *batch[0])
            ]
            tasks += [functools.partial(_ahead, self.space, *trial) for trial in batch[1:]]
            meanwhile = None
            if self.meanwhile is not None and len(tasks) > 1:
                meanwhile, self.meanwhile = functools.partial(self.meanwhile, self.space), None
            for trial, result in zip(batch, results_of(tasks, self.jobs, meanwhile), strict=True):
                if result is not None:  # a look-ahead that failed: the search decides if it matters
                    self.done[_trial_key(*trial)] = result
        return self.done[key]


def _trial_key(point: tuple[float, float], without: tuple[str, ...]) -> Key:
    return (round(point[0], 9), round(point[1], 9), *without)


def _trial(space: BlendSpace, point: tuple[float, float], without: tuple[str, ...]) -> tuple[set[Key], float]:
    trial = _with_virtual(space, point, without)
    return _keys(trial.diagnostics, virtual=True), _coverage(trial)


def _ahead(
    space: BlendSpace, point: tuple[float, float], without: tuple[str, ...]
) -> tuple[set[Key], float] | None:
    """`_trial` for a look-ahead: a rule that fails here fails again, in order, if the search
    comes to it; an error now would be one the serial search might never raise."""
    try:
        return _trial(space, point, without)
    except Exception:
        return None


def _candidates(
    space: BlendSpace,
    diagnostic: Diagnostic,
    mark: Placeholder,
    without: tuple[str, ...],
    *,
    staying: NDArray[np.float64] | None = None,
    by_name: dict[str, Sample] | None = None,
) -> list[tuple[float, float]]:
    """The rule's position first, then positions around it nearest first (axis units).
    ``staying`` (`_staying` of ``without``) and ``by_name`` (the samples by name) may be given
    when they were made once for many marks.

    Positions closer than `thresholds.too_close` to a sample that stays are left out without a
    simulation: a clip there would add (or grow) a too-close finding, so it can never pass.

    For a sliver the points Delaunay refinement would try come first: its circumcentre is the
    rule's own proposal; its centroid and the middles of its edges follow. Then rings around the
    proposal at half, one and two `thresholds.too_close` (the distance a new clip must keep).
    """
    ranges = space.axis_ranges()
    spans = (ranges[0].maximum - ranges[0].minimum, ranges[1].maximum - ranges[1].minimum)

    def to_norm(p: Sequence[float]) -> tuple[float, float]:
        return (
            (p[0] - ranges[0].minimum) / spans[0] * 100.0,
            (p[1] - ranges[1].minimum) / spans[1] * 100.0,
        )

    def to_axis(n: Sequence[float]) -> tuple[float, float]:
        return (n[0] / 100.0 * spans[0] + ranges[0].minimum, n[1] / 100.0 * spans[1] + ranges[1].minimum)

    origin = to_norm(mark.position)
    extra: list[tuple[float, float]] = []
    if by_name is None:
        by_name = {s.name: s for s in space.samples}
    corners = [to_norm(by_name[n].position) for n in diagnostic.clips if n in by_name]
    if diagnostic.rule == "acute-triangle" and len(corners) == 3:
        extra.append((sum(c[0] for c in corners) / 3, sum(c[1] for c in corners) / 3))
        for i in range(3):
            a, b = corners[i], corners[(i + 1) % 3]
            extra.append(((a[0] + b[0]) / 2, (a[1] + b[1]) / 2))
    tau = space.manifest.model.thresholds.too_close
    ring = []
    for radius in (tau / 2, tau, 2 * tau):
        for step in range(8):
            angle = step * math.pi / 4
            ring.append((origin[0] + radius * math.cos(angle), origin[1] + radius * math.sin(angle)))
    inside = [p for p in extra + ring if -1e-9 <= p[0] <= 100 + 1e-9 and -1e-9 <= p[1] <= 100 + 1e-9]
    inside.sort(key=lambda p: math.hypot(p[0] - origin[0], p[1] - origin[1]))
    points = [mark.position] + [to_axis(p) for p in inside]
    # Compared where the clip would be placed: snapped to the grid like any sample.
    snapped = [to_norm((space.axes[0].snap(p[0]), space.axes[1].snap(p[1]))) for p in points]
    return [
        p
        for p, near in zip(
            points,
            _near_samples(snapped, _staying(space, without) if staying is None else staying, tau),
            strict=True,
        )
        if not near
    ]


# The thresholds whose squares stay far inside float64's normal range (see `_near_samples`).
_PREFILTERED = (1e-100, 1e100)


def _near_samples(points: list[tuple[float, float]], staying: NDArray[np.float64], tau: float) -> list[bool]:
    """For each point, whether a staying sample is nearer than ``tau`` (normalised units).

    The squared distances of every point to every sample are one array operation. A point with
    a sample clearly inside ``tau`` is near, one with every sample clearly beyond it is not, and
    only the samples within a relative margin of ``tau`` are measured again with `math.hypot`,
    the test's own distance. For a ``tau`` in `_PREFILTERED` the squares near ``tau**2`` are
    normal floats, whose rounding the margin covers many times, so no answer changes; any other
    ``tau`` (a threshold of 1e-200 squares to 0) is scanned as before, sample by sample."""
    if not points or not len(staying):
        return [False] * len(points)
    if not _PREFILTERED[0] <= tau <= _PREFILTERED[1]:
        everyone = staying.tolist()
        return [_within(point, everyone, tau) for point in points]
    at = np.array(points, dtype=np.float64)
    offsets = staying[None, :, :] - at[:, None, :]
    squares = np.einsum("ijk,ijk->ij", offsets, offsets)
    near = (squares < (tau * (1.0 - 1e-6)) ** 2).any(axis=1)
    # Written as "not beyond" so that a NaN distance is measured too, as the scan would.
    unsure = ~(squares >= (tau * (1.0 + 1e-6)) ** 2)
    answers: list[bool] = near.tolist()
    for index in np.flatnonzero(~near & unsure.any(axis=1)).tolist():
        answers[index] = _within(points[index], staying[unsure[index]].tolist(), tau)
    return answers


def _within(point: tuple[float, float], samples: list[list[float]], tau: float) -> bool:
    """The scan itself: whether a sample is not at least ``tau`` from ``point`` (`math.hypot`;
    a NaN distance counts as near, as it fails the comparison)."""
    x, y = point
    return not all(math.hypot(x - qx, y - qy) >= tau for qx, qy in samples)


def _staying(space: BlendSpace, without: tuple[str, ...]) -> NDArray[np.float64]:
    """Normalised positions (`BlendSpace.normalised_positions`, the same arithmetic as
    `_candidates`' ``to_norm``) of the samples a trial keeps, as an (n, 2) array: the nearness
    test of every candidate is one array operation instead of a loop over the library."""
    kept = np.array([s.name not in without for s in space.samples], dtype=bool)
    normalised: NDArray[np.float64] = space.normalised_positions()[kept]
    return normalised


def _with_virtual(space: BlendSpace, point: tuple[float, float], without: tuple[str, ...] = ()) -> BlendSpace:
    """``space`` with one more sample, measured exactly at ``point`` (and the samples ``without``
    taken out), analysed again."""
    nearest = min(
        space.samples, key=lambda s: (s.position[0] - point[0]) ** 2 + (s.position[1] - point[1]) ** 2
    )
    features = dict(nearest.clip.measurement.features)
    features[space.axes[0].feature] = float(point[0])
    features[space.axes[1].feature] = float(point[1])
    # The clip an author will make there has a cadence and foot timing of its own: the virtual one
    # borrows none, so gait rules (cadence-mismatch, foot-phase-mismatch) do not judge a guess.
    measurement = replace(
        nearest.clip.measurement,
        features=features,
        in_place=False,
        notes=[],
        gait_period=None,
        contacts=None,
        plant_phases=None,
    )
    virtual = MeasuredClip(
        VIRTUAL,
        Path(VIRTUAL),
        ClipEntry(path=VIRTUAL),
        nearest.clip.line,
        nearest.clip.column,
        measurement,
        extra={"virtual": True},
    )
    kept = [s.clip for s in space.samples if s.name not in without]
    trial = assemble(space.manifest, [*kept, virtual])
    flags = {s.name: (s.generated, s.fix) for s in space.samples}
    for sample in trial.samples:
        sample.generated, sample.fix = flags.get(sample.name, (False, None))
    trial.layer_spaces = space.layer_spaces
    trial.rules = space.rules
    run_rules(trial)  # not anchored: a finding's identity (rule, clips, position) needs no line
    return trial


def _key(diagnostic: Diagnostic) -> Key:
    if diagnostic.clips:
        return (diagnostic.rule, frozenset(diagnostic.clips))
    position = None if diagnostic.position is None else tuple(round(v, 6) for v in diagnostic.position)
    return (diagnostic.rule, position)


def _keys(diagnostics: Iterable[Diagnostic], *, virtual: bool = False) -> set[Key]:
    """Identities of the errors and warnings (not counting what is said of the virtual clip alone)."""
    found = set()
    for d in diagnostics:
        if d.severity not in SEVERE:
            continue
        if virtual and d.clips == (VIRTUAL,) and d.rule not in _CLIP_LEVEL_OK:
            continue
        found.add(_key(d))
    return found


def _coverage(space: BlendSpace) -> float:
    return hull_coverage([(float(x), float(y)) for x, y in space.normalised_positions()])


def _unique(marks: Iterable[Placeholder]) -> list[Placeholder]:
    seen: set[tuple[tuple[float, float], str]] = set()
    out = []
    for mark in marks:
        key = ((round(mark.position[0], 6), round(mark.position[1], 6)), mark.priority)
        if key not in seen:
            seen.add(key)
            out.append(mark)
    return out
