"""Placeholder simulations side by side (`--jobs`): the search makes the trials it would make
alone, in the same order, so its answer is the serial one; the look-ahead only moves work to
another process. And `forked.results_of`, which carries the trials' results back."""

from __future__ import annotations

import copy
import math
import os
import re
from pathlib import Path

import pytest

from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline import forked, placeholders
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.space.model import BlendSpace
from blendspace_pipeline.writers.bvh import write_bvh_clip

SAMPLE = Path(__file__).resolve().parents[1] / "sample_project" / "manifest.yaml"
pytestmark = pytest.mark.skipif(not forked.can_fork(), reason="needs fork")


def _answer(space: BlendSpace) -> list[object]:
    return [(d.rule, d.clips, d.hint, d.placeholders) for d in space.diagnostics] + [space.placeholders]


@pytest.fixture(scope="module")
def analysed() -> BlendSpace:
    space = analyse(SAMPLE, converge=False)
    assert any(p.priority == "suggested" for d in space.diagnostics for p in d.placeholders)
    return space


def _converged(space: BlendSpace, jobs: int) -> BlendSpace:
    copied = copy.deepcopy(space)
    placeholders.converge_placeholders(copied, jobs=jobs)
    return copied


def test_side_by_side_gives_the_serial_answer_and_runs_trials_in_other_processes(
    analysed: BlendSpace, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(placeholders, "PARALLEL_FROM", 0)  # the 13-clip sample: fork anyway
    serial = _converged(analysed, 1)
    where: list[int] = []
    with_virtual = placeholders._with_virtual

    def recorded(space: BlendSpace, point: tuple[float, float], without: tuple[str, ...] = ()) -> BlendSpace:
        where.append(os.getpid())  # in a forked child this list is the child's copy
        return with_virtual(space, point, without)

    monkeypatch.setattr(placeholders, "_with_virtual", recorded)
    batches: list[int] = []

    def counted(tasks: list[forked.Task], jobs: int, meanwhile: forked.Task | None = None) -> list[object]:
        batches.append(len(tasks))
        return forked.results_of(tasks, jobs, meanwhile)

    monkeypatch.setattr(placeholders, "results_of", counted)
    parallel = _converged(analysed, 2)
    assert _answer(parallel) == _answer(serial)
    assert max(batches) == 2, "no trial was made beside another"
    # Each batch's first trial ran here; the look-aheads ran in children.
    assert len(where) == len(batches)


def test_a_look_ahead_the_serial_search_never_makes_cannot_fail_the_build(
    analysed: BlendSpace, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A rule that crashes on a position the serial search never tries must not surface because
    a look-ahead tried it (the serial search would have built fine)."""
    monkeypatch.setattr(placeholders, "PARALLEL_FROM", 0)
    tried: set[tuple[float, float]] = set()
    with_virtual = placeholders._with_virtual

    def recording(space: BlendSpace, point: tuple[float, float], without: tuple[str, ...] = ()) -> BlendSpace:
        tried.add((round(point[0], 9), round(point[1], 9)))
        return with_virtual(space, point, without)

    monkeypatch.setattr(placeholders, "_with_virtual", recording)
    serial = _converged(analysed, 1)
    serial_points = set(tried)

    def crashing_off_path(
        space: BlendSpace, point: tuple[float, float], without: tuple[str, ...] = ()
    ) -> BlendSpace:
        if (round(point[0], 9), round(point[1], 9)) not in serial_points:
            raise RuntimeError("a studio rule's bug at a position the search never reaches")
        return with_virtual(space, point, without)

    monkeypatch.setattr(placeholders, "_with_virtual", crashing_off_path)
    assert _answer(_converged(analysed, 2)) == _answer(serial)


def _simulation_note(hint: str) -> str:
    return hint[hint.index("tried by simulation") :]


def test_a_moved_coverage_placeholder_is_named_once_with_what_was_tested(tmp_path: Path) -> None:
    """Three clips on one line: the uncovered-area marks all move to the same position. The note
    names it once, and says what the simulation tested for that rule (coverage grew), not that
    the finding went away (one line of clips stays uncovered)."""
    clips = tmp_path / "clips"
    clips.mkdir()
    for spec in [
        GaitSpec("idle", duration=2.0),
        GaitSpec("walk_fwd", speed=1.4),
        GaitSpec("run_fwd", speed=4.0, duration=0.8, stride_length=2.6),
    ]:
        write_bvh_clip(generate(spec, source=clips / f"{spec.name}.bvh"), clips / f"{spec.name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: loco\nclips: [{path: clips/*.bvh}]\naxes:\n"
        "  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}\n"
        "  y: {feature: speed, min: -3, max: 6, divisions: 90}\n",
        encoding="utf-8",
    )
    coverage = next(d for d in analyse(manifest).diagnostics if d.rule == "uncovered-area")
    note = _simulation_note(coverage.hint or "")
    positions = re.findall(r"\([^()]*\)", note)
    assert positions and len(positions) == len(set(positions)), note
    assert positions == [f"({x:.3g}, {y:.3g})" for x, y in (p.position for p in coverage.placeholders)]
    assert note == (
        f"tried by simulation, a clip at {', '.join(positions)} covers more of the space without adding a finding"
    )


def test_a_moved_placeholder_of_another_rule_removes_the_finding(analysed: BlendSpace) -> None:
    """For every rule but uncovered-area the simulation tested that the finding is gone."""
    moved = [d for d in _converged(analysed, 1).diagnostics if d.hint and "tried by simulation" in d.hint]
    assert moved and all(d.rule != "uncovered-area" for d in moved)
    for diagnostic in moved:
        note = _simulation_note(diagnostic.hint or "")
        assert re.fullmatch(r"tried by simulation, a clip at .+ removes it without adding a finding", note)


def test_results_come_back_in_order_and_the_first_failure_in_order_is_raised() -> None:
    assert forked.results_of([lambda: 1, lambda: {"a": (2, 3)}, lambda: None, lambda: os.getpid()], 3)[
        :3
    ] == [
        1,
        {"a": (2, 3)},
        None,
    ]
    assert forked.results_of([lambda: os.getpid(), lambda: os.getpid()], 2)[1] != os.getpid()
    assert forked.results_of([lambda: os.getpid(), lambda: os.getpid()], 1) == [os.getpid()] * 2

    def fails(text: str) -> forked.Task:
        def task() -> None:
            raise ValueError(text)

        return task

    with pytest.raises(ValueError, match="child"):
        forked.results_of([lambda: 1, fails("child"), fails("later child")], 3)
    with pytest.raises(ValueError, match="here"):
        forked.results_of([fails("here"), fails("child")], 2)


def test_with_work_meanwhile_every_task_runs_in_a_child_and_the_serial_error_is_raised() -> None:
    here: list[int] = []
    pids = forked.results_of([os.getpid, os.getpid], 2, meanwhile=lambda: here.append(os.getpid()))
    assert here == [os.getpid()] and os.getpid() not in pids and len(set(pids)) == 2
    # Without children (jobs 1) the work is done first, then the tasks, here.
    order: list[str] = []
    assert forked.results_of(
        [lambda: order.append("task") or 1], 1, meanwhile=lambda: order.append("meanwhile")
    ) == [1]
    assert order == ["meanwhile", "task"]

    def fails(text: str) -> forked.Task:
        def task() -> None:
            raise ValueError(text)

        return task

    with pytest.raises(ValueError, match="first"):
        forked.results_of([fails("first"), fails("second")], 2, meanwhile=lambda: None)


def test_the_work_meanwhile_is_done_once_beside_the_first_simulations(
    analysed: BlendSpace, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`build` makes the samples' documents while the first batch of simulations runs."""
    monkeypatch.setattr(placeholders, "PARALLEL_FROM", 0)
    serial = _converged(analysed, 1)
    seen: list[tuple[int, int]] = []
    copied = copy.deepcopy(analysed)
    placeholders.converge_placeholders(
        copied, jobs=2, meanwhile=lambda space: seen.append((id(space), os.getpid()))
    )
    assert seen == [(id(copied), os.getpid())]
    assert _answer(copied) == _answer(serial)
    # Nothing simulated side by side (jobs 1): not called, the caller does the work itself.
    placeholders.converge_placeholders(
        copy.deepcopy(analysed), jobs=1, meanwhile=lambda space: seen.append((0, 0))
    )
    assert len(seen) == 1


def _scan_staying(space: BlendSpace, without: tuple[str, ...]) -> list[tuple[float, float]]:
    """The staying samples as the search listed them before `_staying`: one Python tuple each."""
    ranges = space.axis_ranges()
    spans = (ranges[0].maximum - ranges[0].minimum, ranges[1].maximum - ranges[1].minimum)
    return [
        (
            (s.position[0] - ranges[0].minimum) / spans[0] * 100.0,
            (s.position[1] - ranges[1].minimum) / spans[1] * 100.0,
        )
        for s in space.samples
        if s.name not in without
    ]


def _scan_near(
    points: list[tuple[float, float]], staying: list[tuple[float, float]], tau: float
) -> list[bool]:
    """The nearness test as the search made it before `_near_samples`: every staying sample."""
    return [not all(math.hypot(x - q[0], y - q[1]) >= tau for q in staying) for x, y in points]


@pytest.mark.parametrize("too_close", [None, 4.0, 12.0])
def test_candidates_keep_the_positions_the_scan_kept(
    analysed: BlendSpace, too_close: float | None, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The vectorised nearness test (`_staying`, `_near_samples`) keeps exactly the candidates the
    scan of every staying sample kept, for every suggested mark of the sample project, with and
    without the members a too-close marker takes out."""
    space = copy.deepcopy(analysed)
    if too_close is not None:
        space.manifest.model.thresholds.too_close = too_close
    marks = [
        (diagnostic, mark, without)
        for diagnostic in space.diagnostics
        for mark in diagnostic.placeholders
        if mark.priority == "suggested"
        for without in {(), tuple(diagnostic.clips)}
    ]
    assert len(marks) >= 4
    new = [placeholders._candidates(space, *mark) for mark in marks]
    # The search's own lists (the staying samples made once per `without`) are the same.
    trials = placeholders._Trials(space, 1)
    for index, (diagnostic, mark, without) in enumerate(trials.marks):
        direct = placeholders._candidates(space, diagnostic, mark, without)
        assert trials.candidates(index) == direct[: placeholders.MAX_TRIES]
    monkeypatch.setattr(placeholders, "_staying", _scan_staying)
    monkeypatch.setattr(placeholders, "_near_samples", _scan_near)
    assert new == [placeholders._candidates(space, *mark) for mark in marks]
