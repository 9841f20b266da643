"""Shortcuts of the edit path give what the slow ways gave: `relative_path` makes each folder
relative once and joins the file name (the text of `os.path.relpath` of the whole path, paths
that lead back into the base's own folder included); stamps serialise file states as `asdict`;
what the build server warms is what a build computes."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from blendspace_pipeline.pipeline.stamp import FileState, _as_dict, file_state
from blendspace_pipeline.pipeline.to_document import relative_path

CASES = [
    "/a/b/c.bvh",
    "a/b.bvh",
    "../x/y.bvh",
    "/tmp/p/z.usda",
    "/",
    ".",
    "..",
    "a/..",
    "/a/b/../c.bvh",
    "c.bvh",
    "/tmp/c.bvh",
    "/tmp/out/c.bvh",
    "/tmp/out",
    "/tmp/out/../out/d.bvh",
    "out/x/../y",
    "out",
]
BASES = ["/tmp/out", "out", "/", ".", "/a/b", "../q", "/tmp/out/sub"]


@pytest.mark.parametrize("base", BASES)
def test_relative_path_is_relpath_of_the_whole_path(
    base: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    for case in CASES:
        expected = Path(os.path.relpath(Path(case), Path(base))).as_posix()
        assert relative_path(Path(case), Path(base)) == expected, case


def test_relative_path_follows_the_working_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Relative paths are taken from the working folder of the moment (a resident server moves)."""
    (tmp_path / "one").mkdir()
    (tmp_path / "two" / "deep").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "one")
    first = relative_path(Path("clip.bvh"), tmp_path)
    monkeypatch.chdir(tmp_path / "two" / "deep")
    assert (first, relative_path(Path("clip.bvh"), tmp_path)) == ("one/clip.bvh", "two/deep/clip.bvh")


def test_stamp_file_states_serialise_as_asdict(tmp_path: Path) -> None:
    (tmp_path / "a.bvh").write_text("x\n", encoding="utf-8")
    for state in (file_state(tmp_path / "a.bvh"), file_state(tmp_path), file_state(tmp_path / "gone")):
        assert json.dumps(_as_dict(state)) == json.dumps(dataclasses.asdict(state))
    assert list(_as_dict(FileState("p", 1, 2, "h"))) == [f.name for f in dataclasses.fields(FileState)]


def test_snap_rounds_as_numpy_did() -> None:
    from blendspace_pipeline.space.placement import Axis

    def numpy_snap(axis: Axis, value: float) -> float:
        index = np.round((value - axis.minimum) / axis.step)
        return round(float(axis.minimum + index * axis.step), 9) + 0.0

    rng = np.random.default_rng(2)
    axes = [
        Axis("x", "speed", 0.0, 5.0, 20),
        Axis("x", "turn_rate", -180.0, 180.0, 8),
        Axis("y", "d", -0.0, 1.0, 3),
    ]
    halves = [axis.minimum + (k + 0.5) * axis.step for axis in axes for k in range(-3, 25)]  # ties
    values = halves + rng.uniform(-400, 400, 2000).tolist() + [0.0, -0.0, 1e300, -1e300, math.inf, -math.inf]
    for axis in axes:
        for value in values:
            assert repr(axis.snap(value)) == repr(numpy_snap(axis, value)), (axis, value)
        assert math.isnan(axis.snap(math.nan))


def test_what_the_server_warms_is_what_a_build_computes(tmp_path: Path) -> None:
    """`outputs.warm` (the build server calls it before it forks commands) fills the code digest,
    the writer libraries' versions and the legend's rendered text; a PNG drawn with them is the
    PNG drawn without, and the remembered text cannot be changed by a drawing."""
    from test_report import sample_document

    from blendspace_pipeline.pipeline import outputs
    from blendspace_pipeline.report import png

    doc = sample_document()
    for cached in (outputs._code_digest, outputs._library_version, png._text_coverage):
        cached.cache_clear()
    png.write_png(doc, tmp_path / "cold.png")
    digest = outputs._code_digest()
    png._text_coverage.cache_clear()
    outputs._code_digest.cache_clear()
    outputs.warm()
    assert outputs._code_digest.cache_info().currsize == 1 and outputs._code_digest() == digest
    assert outputs._library_version.cache_info().currsize == 3  # usd-core, OpenImageIO, numpy
    if png._font() is not None:
        assert png._text_coverage.cache_info().currsize == len(png.LEGEND) + 1
        alpha = png._text_coverage(png.LEGEND[0][1], 13 * png.SCALE, png._font(), "left")[0]
        assert not alpha.flags.writeable
    png.write_png(doc, tmp_path / "warm.png")
    assert (tmp_path / "warm.png").read_bytes() == (tmp_path / "cold.png").read_bytes()


def test_without_a_font_the_server_warms_nothing_and_each_command_warns(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A warning is shown once per process, and a forked command inherits that memory: the
    server's warm-up must not warn, or no served build would tell its caller the PNG has no text."""
    import warnings

    from test_report import sample_document

    from blendspace_pipeline.report import png

    monkeypatch.setattr(png, "_found_font", lambda: None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        png.warm()
    assert caught == []
    with pytest.warns(UserWarning, match="found no font"):
        png.write_png(sample_document(), tmp_path / "plain.png")


def test_sample_documents_made_ahead_are_the_ones_to_document_makes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`SampleDocsAhead`: made while the simulations run, taken only while the sample reads the
    same; a sample that moved, a clip given its file name later, another output or working folder
    get a new document. The document is the same either way."""
    from dataclasses import replace

    from blendspace_pipeline.pipeline.analysis import analyse
    from blendspace_pipeline.pipeline.to_document import SampleDocsAhead, to_document

    space = analyse(Path(__file__).resolve().parents[1] / "sample_project" / "manifest.yaml", converge=False)
    out = tmp_path / "out"
    prepared = SampleDocsAhead(lambda _space: out)
    prepared.prepare(space)
    made = {id(s): doc for s, (_, doc) in zip(space.samples, prepared.docs.values(), strict=True)}
    first, second, third = space.samples[:3]
    first.position = (first.position[0] + 1.0, first.position[1])
    second.clip.source = tmp_path / "elsewhere" / "renamed.bvh"
    third.clip = replace(third.clip, measurement=replace(third.clip.measurement))
    document = to_document(space, out, prepared)
    assert document.model_dump_json() == to_document(space, out).model_dump_json()
    taken = [doc is made[id(s)] for s, doc in zip(space.samples, document.samples, strict=True)]
    assert taken == [False, False, False] + [True] * (len(space.samples) - 3)
    assert prepared.docs == {}  # each taken once
    # Another output folder, or another working folder: none is taken.
    for folder, cwd in ((tmp_path / "other", None), (out, tmp_path)):
        prepared.prepare(space)
        kept = dict(prepared.docs)
        if cwd is not None:
            monkeypatch.chdir(cwd)
        document = to_document(space, folder, prepared)
        assert not any(doc is kept[id(s)][1] for s, doc in zip(space.samples, document.samples, strict=True))
        assert document.model_dump_json() == to_document(space, folder).model_dump_json()

    def refuses(_space: object) -> Path:
        raise ValueError("no output folder")

    failing = SampleDocsAhead(refuses)
    failing.prepare(space)  # an optimisation: never an error of its own
    assert failing.docs == {}
    assert to_document(space, out, failing).model_dump_json() == to_document(space, out).model_dump_json()
