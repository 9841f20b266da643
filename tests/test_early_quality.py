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


def test_while_the_maps_are_made_the_report_is_drafted_and_the_outputs_are_the_same(
    manifest: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The maps are a cold build's longest task: once this process has written what it writes
    beside them, it draws the report's draft (everything but the blend quality), and the HTML
    written after the maps only adds them. Every output is the one a single process writes."""
    from test_incremental import _same_outputs

    from blendspace_pipeline.report import html

    alone = manifest.parent / "out1"
    _build(manifest, 1)
    # The child is never done before the writers plan (as on a 1,000-clip build).
    monkeypatch.setattr(early_quality.EarlyQuality, "ready", lambda self: False)
    drafted: list[bool] = []  # per draft: drawn before the blend quality was set
    used = manifest.parent / "used.txt"  # the forked HTML writer's draft: the one drawn here
    draft_report, render_html = html.draft_report, html.render_html

    def drafting(doc: BlendSpaceDocument) -> html.ReportDraft:
        drafted.append(doc.blend_quality is None)
        return draft_report(doc)

    def rendering(doc: BlendSpaceDocument, **kwargs: object) -> str:
        draft = kwargs.get("draft")
        used.write_text(str(isinstance(draft, html.ReportDraft) and draft.doc is doc))
        return render_html(doc, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(html, "draft_report", drafting)
    monkeypatch.setattr(html, "render_html", rendering)
    _build(manifest, 2)
    _same_outputs(alone, manifest.parent / "out2")
    assert drafted == [True]  # drawn once, here, before the blend quality was set
    assert used.read_text() == "True"


def test_a_report_finished_from_its_draft_is_the_page_drawn_at_once(manifest: Path) -> None:
    from blendspace_pipeline.report import html

    built = BlendSpaceDocument.model_validate_json(_build(manifest, 1))
    assert built.blend_quality is not None and built.blend_quality.foot_skate is not None
    whole = html.render_html(built, stamp="then")
    blind = built.model_copy(update={"blend_quality": None})
    draft = html.draft_report(blind)  # what the build draws while the maps are made
    blind.blend_quality = built.blend_quality  # ...and then sets
    assert html.render_html(blind, stamp="then", draft=draft) == whole
    # A draft of another document object is not trusted: the page is drawn afresh.
    assert html.render_html(built, stamp="then", draft=draft) == whole
    other = built.model_copy(update={"name": "other"})
    assert html.render_html(other, stamp="then", draft=draft) == html.render_html(other, stamp="then")


def test_the_child_s_document_holds_what_the_maps_read(manifest: Path) -> None:
    """The child makes `maps_document` (no contacts, markers, findings, layers): the same maps and
    the same digest as the whole document; and the digest moves with every field the maps read
    (positions, features, the clips' gait periods, triangles, axes)."""
    from blendspace_pipeline.pipeline.blend_quality import blend_quality
    from blendspace_pipeline.pipeline.outputs import build
    from blendspace_pipeline.pipeline.to_document import maps_document

    result = build(manifest, manifest.parent / "out", fix=False)
    whole = result.document.model_copy(update={"blend_quality": None}, deep=True)
    lite = maps_document(result.space, result.out_dir)
    assert lite.diagnostics == [] and all(s.markers is None and s.contacts is None for s in lite.samples)
    assert any(s.markers for s in whole.samples)
    assert early_quality.quality_inputs(lite) == early_quality.quality_inputs(whole)
    maps = blend_quality(result.space, lite, {}, sync=result.space.manifest.model.blend.sync)
    assert maps == result.document.blend_quality
    digest = early_quality.quality_inputs(whole)

    def moved(change: str) -> str:
        doc = whole.model_copy(deep=True)
        sample = doc.samples[0]
        if change == "position":
            sample.position = [sample.position[0] + 1e-6, sample.position[1]]
        elif change == "features":
            sample.features = {**sample.features, "forward_speed": sample.features["forward_speed"] + 0.1}
        elif change == "gait_period":
            assert sample.clip is not None
            sample.clip.gait_period = (sample.clip.gait_period or 1.0) + 0.1
        elif change == "triangles":
            doc.triangles = doc.triangles[1:]
        else:
            doc.axes[0].max += 1.0
        return early_quality.quality_inputs(doc)

    for change in ("position", "features", "gait_period", "triangles", "axes"):
        assert moved(change) != digest, change
