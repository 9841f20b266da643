"""Placeholder simulations side by side (`--jobs`): the search makes the trials it would make
alone, in the same order, so its answer is the serial one; the look-ahead only moves work to
another process. And `forked.results_of`, which carries the trials' results back."""

from __future__ import annotations

import copy
import math
import os
from collections.abc import Sequence
from pathlib import Path

import pytest

from blendspace_pipeline.diagnostics import Diagnostic, Placeholder
from blendspace_pipeline.pipeline import forked, placeholders
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.space.model import BlendSpace

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

    def counted(tasks: list[forked.Task], jobs: int) -> list[object]:
        batches.append(len(tasks))
        return forked.results_of(tasks, jobs)

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


def _old_candidates(
    space: BlendSpace, diagnostic: Diagnostic, mark: Placeholder, without: tuple[str, ...]
) -> list[tuple[float, float]]:
    """`placeholders._candidates` as it was before its nearness test was vectorised (a
    Python scan of every staying sample per candidate): the reference the new code must equal."""
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
    staying = [to_norm(s.position) for s in space.samples if s.name not in without]

    def free(p: tuple[float, float]) -> bool:
        # Compared where the clip would be placed: snapped to the grid like any sample.
        snapped = to_norm((space.axes[0].snap(p[0]), space.axes[1].snap(p[1])))
        return all(math.hypot(snapped[0] - q[0], snapped[1] - q[1]) >= tau for q in staying)

    points = [mark.position] + [to_axis(p) for p in inside]
    return [p for p in points if free(p)]


@pytest.mark.parametrize("too_close", [None, 4.0, 12.0])
def test_candidates_keep_the_positions_the_scan_kept(analysed: BlendSpace, too_close: float | None) -> None:
    """The vectorised nearness test (`_near_samples`) keeps exactly the candidates a scan of every
    staying sample kept, for every suggested mark of the sample project, with and without the
    members a too-close marker takes out."""
    space = copy.deepcopy(analysed)
    if too_close is not None:
        space.manifest.model.thresholds.too_close = too_close
    compared = 0
    for diagnostic in space.diagnostics:
        for mark in diagnostic.placeholders:
            if mark.priority != "suggested":
                continue
            for without in {(), tuple(diagnostic.clips)}:
                new = placeholders._candidates(space, diagnostic, mark, without)
                assert new == _old_candidates(space, diagnostic, mark, without)
                compared += 1
    assert compared >= 4
