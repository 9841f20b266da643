"""`build --no-fix --jobs 2` makes the blend quality maps in a child forked before the rules
(`pipeline/early_quality.py`): the same document as one process, whichever way it goes: maps
taken from the child, a rule that moves a sample after the child forked (the child's maps are
refused by digest and made again), a child that fails (made again here)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_incremental import _project

from blendspace_pipeline.checks import rule_engine
from blendspace_pipeline.cli import main
from blendspace_pipeline.pipeline import early_quality, forked
from blendspace_pipeline.space.document import BlendQualityDoc, BlendSpaceDocument

pytestmark = pytest.mark.skipif(not forked.can_fork(), reason="the early maps are made in a forked child")


@pytest.fixture
def manifest(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")  # every map really computed
    return _project(tmp_path / "project")


def _build(manifest: Path, jobs: int) -> bytes:
    out = manifest.parent / f"out{jobs}"
    assert main(["build", str(manifest), "--out", str(out), "--no-fix", "--jobs", str(jobs)]) in (0, 1)
    return (out / "planted.blendspace.json").read_bytes()


def _taken(monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """Whether each build used the child's maps."""
    taken: list[bool] = []
    result = early_quality.EarlyQuality.result

    def recorded(self: early_quality.EarlyQuality, document: BlendSpaceDocument) -> BlendQualityDoc | None:
        maps = result(self, document)
        taken.append(maps is not None)
        return maps

    monkeypatch.setattr(early_quality.EarlyQuality, "result", recorded)
    return taken


def test_the_child_s_maps_are_the_ones_one_process_makes(
    manifest: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    taken = _taken(monkeypatch)
    alone = _build(manifest, 1)
    assert taken == []  # --jobs 1: no child
    assert _build(manifest, 2) == alone
    assert taken == [True]
    assert b'"foot_skate": [' in alone  # there was a foot-skate map to make


def test_a_rule_that_moves_a_sample_after_the_fork_gets_maps_made_again(
    manifest: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    run_rules = rule_engine.run_rules

    def moving(space, *args, **kwargs):  # type: ignore[no-untyped-def]
        run_rules(space, *args, **kwargs)
        first = space.samples[0]
        first.position = (first.position[0] + 1.0, first.position[1])  # a badly behaved studio rule

    monkeypatch.setattr(rule_engine, "run_rules", moving)
    monkeypatch.setattr("blendspace_pipeline.pipeline.analysis.run_rules", moving)
    taken = _taken(monkeypatch)
    alone = _build(manifest, 1)
    assert _build(manifest, 2) == alone
    assert taken == [False]


def test_a_child_that_fails_leaves_the_maps_to_this_process(
    manifest: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def failing(*args: object) -> None:
        raise RuntimeError("the child broke")

    monkeypatch.setattr(early_quality, "_maps", failing)
    taken = _taken(monkeypatch)
    alone = _build(manifest, 1)
    assert _build(manifest, 2) == alone
    assert taken == [False]
