"""The committed JSON Schemas in `schemas/` must be exactly what the models generate today."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from blendspace_pipeline.commands.schema import SCHEMAS, schema_text

SCHEMA_DIR = Path(__file__).resolve().parents[1] / "schemas"

# Every block of spec.md's manifest, plus layers and the skeleton extensions.
FULL_MANIFEST = """\
schema_version: 1
name: locomotion
clips:
  - path: clips/*.bvh
  - {path: mocap/run_fwd.bvh, name: run_fwd, range: [0.5, 2.5], expect: {turn_rate: 0}, position: [0, 4.5],
     ignore: [{rule: too-close, reason: "kept for the style"}]}
skeleton: {units: 0.056444, up: z, root: Hips, mirror: {left: Left, right: Right}, forward: +y, tpose: drop}
axes:
  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}
  y: {feature: speed, min: -3, max: 6, divisions: 90}
thresholds: {crossing_axis: 5, too_close: 8, acute_angle: 15, misalignment: 3}
rules: {select: [all], ignore: [uncovered-area], severity: {too-close: error}}
fixes: {mirror: true, axis_clips: true, too_close: keep-representative, straighten: false}
plugins: [studio_rules]
layers:
  - {name: lateral, kind: beta, manifest: lateral.yaml}
  - {name: drunk, kind: style, clips: [styles/a.bvh, {path: styles/b.bvh}],
     mask: {joints: {Hips: 1.0}, default: 0.0}}
output: {dir: build, formats: [json, usd, html, png]}
"""


@pytest.mark.parametrize("kind", sorted(SCHEMAS))
def test_committed_schema_matches_the_models(kind: str) -> None:
    file_name = SCHEMAS[kind][2]
    committed = SCHEMA_DIR / file_name
    regenerate = f"blendspace schema {kind} > schemas/{file_name}"
    assert committed.is_file(), f"schemas/{file_name} is missing; create it with:\n    {regenerate}"
    if committed.read_text(encoding="utf-8") != schema_text(kind):
        pytest.fail(
            f"schemas/{file_name} is out of date with the pydantic models; regenerate it and commit:\n"
            + "\n".join(f"    blendspace schema {k} > schemas/{SCHEMAS[k][2]}" for k in sorted(SCHEMAS)),
            pytrace=False,
        )


def test_manifest_schema_accepts_the_spec_example_and_rejects_typos() -> None:
    """Editors validate with the committed schema, so it must agree with the loader."""
    jsonschema = pytest.importorskip("jsonschema")
    from ruamel.yaml import YAML

    schema = json.loads((SCHEMA_DIR / "manifest.schema.json").read_text(encoding="utf-8"))
    validator = jsonschema.Draft202012Validator(schema)
    example = YAML(typ="safe").load(FULL_MANIFEST)
    assert [error.message for error in validator.iter_errors(example)] == []
    example["clips"][1]["rnage"] = example["clips"][1].pop("range")
    example["axes"]["x"]["feature"] = "sped"
    example["layers"][0]["kind"] = "bta"
    assert len(list(validator.iter_errors(example))) == 3
