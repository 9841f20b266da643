"""`evaluate_many` equals `evaluate` query by query: inside, on edges and vertices, outside the
hull, with beta and style layers (masked or not), culling, playback rates and degenerate spaces;
and on a document built from real clips."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import shared_data
from test_evaluate import (
    COLLINEAR,
    LOCOMOTION,
    TRIANGLE,
    UNIT_BOX,
    _clip_info,
    _sample,
    _style,
    make_doc,
)

from blendspace_pipeline.cli import main
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.evaluate import BatchEvaluator, Evaluation, evaluate, evaluate_many
from blendspace_pipeline.space.layers_doc import read_document


def assert_same(batch: Evaluation, single: Evaluation) -> None:
    got, want = batch.to_json(), single.to_json()
    # Heaviest first in both; entries whose weights tie up to rounding may swap, so compare by clip.
    weights = [w["weight"] for w in got["weights"]]
    assert weights == sorted(weights, reverse=True)
    by_clip = {(w["clip"], w["layer"]): w for w in got.pop("weights")}
    wanted = {(w["clip"], w["layer"]): w for w in want.pop("weights")}
    _approx_nested(by_clip, wanted)
    _approx_nested(got, want)


def _approx_nested(got: Any, want: Any) -> None:
    """pytest.approx does not recurse into lists of dicts: compare leaf by leaf."""
    if isinstance(want, dict):
        assert set(got) == set(want), (got, want)
        for key in want:
            _approx_nested(got[key], want[key])
    elif isinstance(want, list):
        assert len(got) == len(want)
        for g, w in zip(got, want, strict=True):
            _approx_nested(g, w)
    elif isinstance(want, float):
        assert got == pytest.approx(want, abs=1e-9)
    else:
        assert got == want


def _queries(doc: BlendSpaceDocument, rng: np.random.Generator, count: int) -> np.ndarray:
    """Random queries over (and a little beyond) the axes, plus every vertex and edge midpoint."""
    lows = np.array([doc.axes[0].min, doc.axes[1].min])
    highs = np.array([doc.axes[0].max, doc.axes[1].max])
    span = highs - lows
    points = [rng.uniform(lows - 0.2 * span, highs + 0.2 * span, size=(count, 2))]
    positions = np.array([s.position for s in doc.samples], dtype=float)
    points.append(positions)
    for a, b, c in doc.triangles:
        points.append(
            np.array([(positions[a] + positions[b]) / 2, (positions[a] + positions[b] + positions[c]) / 3])
        )
    return np.concatenate(points)


def _check(doc: BlendSpaceDocument, count: int = 400, **options: Any) -> None:
    queries = _queries(doc, np.random.default_rng(5), count)
    batch = evaluate_many(doc, queries, **options)
    assert len(batch) == len(queries)
    for row, (x, y) in enumerate(queries):
        assert_same(batch.evaluation(row), evaluate(doc, float(x), float(y), **options))


@pytest.mark.parametrize("cull", [0.0, 0.01, 0.2])
def test_batch_equals_single_on_the_main_space(cull: float) -> None:
    _check(make_doc(LOCOMOTION), cull=cull)


def test_batch_equals_single_with_beta_and_style_layers_and_rates() -> None:
    beta = {
        "name": "lateral",
        "kind": "beta",
        "source": "lateral.yaml",
        "samples": [
            _sample("a", (0.0, 0.0), 1.0),
            _sample("e", (1.0, 0.0), 2.0),
            _sample("f", (0.0, 1.0), None),
        ],
        "triangles": [[0, 1, 2]],
    }
    masked = _style(mask={"joints": {"Hips": 1.0, "Spine": 0.5}, "default": 0.0}) | {"name": "masked"}
    masked["samples"][1] = {"name": "a", "source": "clips/a.bvh", "position": [-1.0], "features": {}}
    raw = make_doc(
        TRIANGLE, axes=UNIT_BOX, durations={"a": 1.0, "b": 2.0}, layers=[beta, _style(), masked]
    ).model_dump()
    raw["samples"][2]["clip"] = _clip_info(1.5, gait_period=None)  # c: no gait, plays at rate 1
    doc = BlendSpaceDocument.model_validate(raw)
    for values in ({}, {"lateral": 0.4}, {"drunk": 0.3, "lateral": 1.0}, {"drunk": 1.0, "masked": 0.5}):
        _check(doc, count=150, layers=values, cull=0.0)
        _check(doc, count=150, layers=values)
    _check(doc, count=150, layers={"masked": 0.6, "drunk": 0.2}, joint="Spine")


@pytest.mark.parametrize("points", [COLLINEAR, {"idle": (0.0, 0.0)}])
def test_batch_equals_single_in_degenerate_spaces(points: dict[str, tuple[float, float]]) -> None:
    _check(make_doc(points, triangles=[]), count=100)


def test_batch_equals_single_on_hand_edited_triangles() -> None:
    """Triangles that are not scipy's Delaunay (a hand-edited document): no find_simplex shortcut."""
    square = {"a": (-1.0, -1.0), "b": (1.0, -1.0), "c": (1.0, 1.0), "d": (-1.0, 1.0)}
    for triangles in ([[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]):
        doc = make_doc(square, axes=UNIT_BOX, triangles=triangles)
        _check(doc, count=200)


def test_batch_on_a_document_built_from_real_clips(tmp_path: Path) -> None:
    """The Godot TPS demo's strafe cycles built into a space, then queries evaluated both ways."""
    data = shared_data("godot-tps-demo", "SOURCES.md").parent.as_posix()
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: strafe\nclips:\n"
        f"  - path: '{data}/strafe_*-cycle.tres'\n"
        f"  - path: '{data}/Idlecombat-cycle.tres'\n"
        "    ignore: [{rule: in-place-clip, reason: idle}]\n"
        "axes:\n  x: {feature: lateral_speed, min: -3, max: 3, divisions: 60}\n"
        "  y: {feature: forward_speed, min: -3, max: 3, divisions: 60}\n",
        encoding="utf-8",
    )
    out = tmp_path / "out"
    assert main(["build", str(manifest), "--out", str(out), "--format", "json", "--no-fix"]) in (0, 1)
    doc = read_document(next(out.glob("*.blendspace.json")))
    assert len(doc.triangles) == 4
    _check(doc, count=300)


def test_an_evaluator_is_reused_across_batches_and_rejects_bad_layers() -> None:
    doc = make_doc(LOCOMOTION)
    evaluator = BatchEvaluator(doc)
    first = evaluator(np.array([[0.0, 1.0], [45.0, 2.0]]))
    second = evaluator(np.array([[0.0, 1.0]]))
    assert_same(first.evaluation(0), second.evaluation(0))
    from blendspace_pipeline.errors import InputError

    with pytest.raises(InputError, match="no layer"):
        evaluator(np.zeros((1, 2)), layers={"nope": 0.5})


def test_batch_weights_are_the_known_barycentric_oracle() -> None:
    """(0.25, 0.5) in the unit triangle: a .25, b .25, c .5 by construction."""
    doc = make_doc(TRIANGLE, axes=UNIT_BOX)
    batch = evaluate_many(doc, np.array([[0.25, 0.5], [0.0, 0.0]]), cull=0.0)
    names = [[batch.clips[i].name for i in row if i >= 0] for row in batch.clip_index]
    assert names[0] == ["c", "a", "b"] and names[1] == ["a"]
    assert batch.weights[0].tolist() == pytest.approx([0.5, 0.25, 0.25])
    assert not batch.outside_hull.any()


def test_eval_command_evaluates_a_points_file_in_one_batch(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = make_doc(LOCOMOTION)
    path = tmp_path / "space.blendspace.json"
    path.write_text(doc.model_dump_json(), encoding="utf-8")
    points = tmp_path / "points.csv"
    points.write_text("turn_rate,speed\n0,1.4\n45.5,2.0\n500,50\n", encoding="utf-8")
    assert main(["eval", str(path), "--points", str(points), "--format", "json"]) == 0
    results = json.loads(capsys.readouterr().out)
    assert len(results) == 3
    for result, (x, y) in zip(results, [(0.0, 1.4), (45.5, 2.0), (500.0, 50.0)], strict=True):
        want = evaluate(doc, x, y).to_json()
        assert {w["clip"]: w["weight"] for w in result["weights"]} == pytest.approx(
            {w["clip"]: w["weight"] for w in want["weights"]}
        )
        assert result["outside_hull"] == want["outside_hull"]
    assert main(["eval", str(path), "--points", str(points)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == "0,1.4: walk=1.0000" and lines[2].endswith("(outside)")


@pytest.mark.parametrize(
    "header",
    ["speed,turn_rate", "y,x", '"speed", "turn_rate"', "\ufeffspeed,turn_rate", "turn_rate,speed", "x,y"],
)
def test_a_points_header_names_the_columns_in_any_order(
    header: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A header was skipped unread: `speed,turn_rate` then `1.4,0` was evaluated at turn 1.4,
    speed 0 (other clips, other weights), with no word. It names the columns now, by axis or
    feature, as `--at` does."""
    doc = make_doc(LOCOMOTION)
    path = tmp_path / "space.blendspace.json"
    path.write_text(doc.model_dump_json(), encoding="utf-8")
    swapped = header.lstrip("\ufeff").replace('"', "").replace(" ", "") in ("speed,turn_rate", "y,x")
    points = tmp_path / "points.csv"
    points.write_text(f"{header}\n" + ("1.4,30\n" if swapped else "30,1.4\n"), encoding="utf-8")
    assert main(["eval", str(path), "--points", str(points), "--format", "json"]) == 0
    [result] = json.loads(capsys.readouterr().out)
    want = evaluate(doc, 30.0, 1.4).to_json()
    assert {w["clip"]: w["weight"] for w in result["weights"]} == pytest.approx(
        {w["clip"]: w["weight"] for w in want["weights"]}
    )


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("0,1\n2,oops\n", "{points}:2: row 2 is not two numbers"),
        # A header is read, not skipped: one that names no axis is refused.
        ("velocity,turn\n1.4,0\n", "{points}:1: the header row 'velocity,turn' does not name both axes"),
    ],
)
def test_eval_command_rejects_a_bad_points_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, message: str
) -> None:
    path = tmp_path / "space.blendspace.json"
    path.write_text(make_doc(LOCOMOTION).model_dump_json(), encoding="utf-8")
    points = tmp_path / "points.csv"
    points.write_text(content, encoding="utf-8")
    assert main(["eval", str(path), "--points", str(points)]) == 2
    err = capsys.readouterr().err
    assert message.format(points=points) in err and "Traceback" not in err
