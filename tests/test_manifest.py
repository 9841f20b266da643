"""The manifest: spec.md's example, defaults, every error with its line:col and hint, clip paths."""

from __future__ import annotations

import json
import os
import textwrap
import time
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.errors import ManifestError
from blendspace_pipeline.manifest import (
    FEATURE_UNITS,
    FEATURES,
    LoadedManifest,
    ManifestProblemsError,
    load_manifest,
)
from blendspace_pipeline.manifest.models import BetaLayer, ClipEntry, StyleLayer
from blendspace_pipeline.manifest.paths import resolve_clip_files

# spec.md's manifest, verbatim (comments included).
SPEC_EXAMPLE = """\
schema_version: 1
name: locomotion
clips:                         # files or globs, relative to the manifest
  - path: clips/*.bvh
  - path: mocap/run_fwd.bvh
    name: run_fwd              # default: file stem ("<stem>/<animation>" for multi-animation files)
    range: [0.5, 2.5]          # optional trim, seconds
    expect: {turn_rate: 0}     # optional intended feature values (misalignment check)
    position: [0, 4.5]         # optional hand placement, compared with the measured one in the report
    ignore: [{rule: too-close, reason: "kept for the style"}]
skeleton:                      # optional; auto-detected when absent
  units: auto                  # auto|m|cm|mm|in
  up: auto                     # auto|y|z
  root: auto                   # joint whose ground projection is the root motion; auto = hip midpoint
  left_hip: auto
  right_hip: auto
  mirror: auto                 # or {left: Left, right: Right} name tokens to swap
axes:
  x: {feature: turn_rate, min: -180, max: 180, divisions: 100}
  y: {feature: speed, min: -3, max: 6, divisions: 90}    # keep 0 on the grid: idle sits on the main axes
thresholds:                    # distances in normalised axis space (each axis 0..100); angles in degrees
  crossing_axis: 5
  too_close: 8
  acute_angle: 15
  misalignment: 3
rules: {select: [all], ignore: [], severity: {}}
fixes: {mirror: true, axis_clips: true, too_close: report}   # report|keep-representative|merge
plugins: []                    # studio rule modules: importable names or paths
layers: []                     # beta and style layers (see below)
output: {dir: build, formats: [json, usd, html, png]}
"""

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
MINIMAL = "schema_version: 1\nname: walk\nclips:\n  - path: walk.bvh\n"


def write(folder: Path, text: str, name: str = "manifest.yaml") -> Path:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text), encoding="utf-8")
    return path


def touch(folder: Path, *names: str) -> None:
    for name in names:
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(b"")


def load_error(folder: Path, text: str) -> ManifestError:
    with pytest.raises(ManifestError) as caught:
        load_manifest(write(folder, text))
    return caught.value


def where(error: ManifestError) -> tuple[int | None, int | None]:
    return error.line, error.column


# --- valid manifests --------------------------------------------------------------------------------


def test_spec_example_parses(tmp_path: Path) -> None:
    model = load_manifest(write(tmp_path, SPEC_EXAMPLE)).model
    assert model.name == "locomotion"
    assert [c.path for c in model.clips] == ["clips/*.bvh", "mocap/run_fwd.bvh"]
    run = model.clips[1]
    assert run.name == "run_fwd"
    assert run.range == (0.5, 2.5)
    assert run.expect == {"turn_rate": 0.0}
    assert run.position == (0.0, 4.5)
    assert [(i.rule, i.reason) for i in run.ignore] == [("too-close", "kept for the style")]
    assert (model.axes.x.feature, model.axes.x.min, model.axes.x.max, model.axes.x.divisions) == (
        "turn_rate",
        -180,
        180,
        100,
    )
    assert model.fixes.too_close == "report"
    assert model.output.formats == ["json", "usd", "html", "png"]


def test_minimal_manifest_gets_the_spec_defaults(tmp_path: Path) -> None:
    model = load_manifest(write(tmp_path, MINIMAL)).model
    spec = load_manifest(write(tmp_path, SPEC_EXAMPLE, "spec.yaml")).model
    # Everything the spec example spells out is also the default.
    for block in ("skeleton", "axes", "thresholds", "rules", "fixes", "output"):
        assert getattr(model, block) == getattr(spec, block), block
    assert model.skeleton.forward == "auto" and model.skeleton.tpose == "auto"
    assert model.fixes.straighten is False
    assert model.thresholds.model_dump() == {
        "crossing_axis": 5,
        "too_close": 8,
        "acute_angle": 15,
        "misalignment": 3,
    }
    assert model.plugins == [] and model.layers == []
    assert model.clips[0].ignore == [] and model.clips[0].name is None


def test_extension_keys_and_spec_layers(tmp_path: Path) -> None:
    model = load_manifest(
        write(
            tmp_path,
            MINIMAL
            + """\
skeleton: {units: 0.056444, mirror: {left: Left, right: Right}, forward: +z, tpose: drop}
layers:
  - {name: lateral, kind: beta, manifest: lateral.yaml}
  - name: drunk
    kind: style
    clips: [styles/drunk_fwd.bvh, {path: styles/drunk_back.bvh, range: [0, 1]}]
    mask: {joints: {Hips: 1.0, LeftUpLeg: 1.0, RightUpLeg: 1.0}, default: 0.0}
""",
        )
    ).model
    assert model.skeleton.units == pytest.approx(0.056444)
    assert model.skeleton.forward == "+z" and model.skeleton.tpose == "drop"
    beta, style = model.layers
    assert isinstance(beta, BetaLayer) and beta.manifest == "lateral.yaml"
    assert isinstance(style, StyleLayer) and style.mask is not None and style.mask.default == 0.0
    assert style.clips[0] == "styles/drunk_fwd.bvh"
    assert isinstance(style.clips[1], ClipEntry) and style.clips[1].range == (0.0, 1.0)


def test_feature_table_matches_spec() -> None:
    assert tuple(FEATURE_UNITS) == FEATURES
    assert FEATURE_UNITS["turn_rate"] == "deg/s" and FEATURE_UNITS["turn"] == "deg"
    assert FEATURE_UNITS["lateral_speed"] == "m/s" and FEATURE_UNITS["duration"] == "s"


# --- validation errors: each at its own line:col, with its key path and a hint ---------------------


def test_unknown_key_names_the_path_suggests_and_lists_valid_keys(tmp_path: Path) -> None:
    error = load_error(
        tmp_path,
        """\
        schema_version: 1
        name: walk
        clips:
          - path: a.bvh
          - path: b.bvh
          - path: c.bvh
            rnage: [0, 1]
        """,
    )
    assert where(error) == (7, 5)
    assert error.message == "clips[2].rnage: unknown key 'rnage'"
    assert error.hint is not None and error.hint.startswith("did you mean 'range'?")
    assert "path, name, range, expect, position, ignore" in error.hint
    assert f"{error.path}:7:5: clips[2].rnage: unknown key 'rnage'" in error.render()


def test_a_number_as_a_key_says_so(tmp_path: Path) -> None:
    """`5: x` said "[5]: Keys should be strings" (pydantic's words) with no hint."""
    error = load_error(tmp_path, MINIMAL + "5: x\n")
    assert where(error) == (5, 1)
    assert error.message == "[5]: a key must be a name, got the number 5"
    assert error.hint is not None and error.hint.startswith("valid keys: schema_version, name, clips")


def test_unknown_top_level_key(tmp_path: Path) -> None:
    error = load_error(tmp_path, MINIMAL + "thresolds: {too_close: 4}\n")
    assert where(error) == (5, 1)
    assert error.message == "thresolds: unknown key 'thresolds'"
    assert error.hint is not None and error.hint.startswith(
        "did you mean 'thresholds'? valid keys: schema_version, "
    )


def test_wrong_type_says_what_was_expected_and_given(tmp_path: Path) -> None:
    error = load_error(
        tmp_path, MINIMAL + "axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: many}\n"
    )
    assert where(error) == (6, 48)
    assert error.message == "axes.x.divisions: expected a whole number, got the text 'many'"
    assert error.hint is not None and "Grid intervals" in error.hint


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("axes:\n  x: {feature: turn_rate, min: -180, max: 180, divisions: true}\n",
         "axes.x.divisions: expected a whole number, got true"),
        ("axes:\n  x: {feature: turn_rate, min: '-180', max: 180, divisions: 72}\n",
         "axes.x.min: expected a number, got the text '-180'"),
        ("fixes: {mirror: 'off'}\n", "fixes.mirror: expected true or false, got the text 'off'"),
        ("fixes: {axis_clips: 1}\n", "fixes.axis_clips: expected true or false, got the number 1"),
        ("thresholds: {too_close: '5'}\n", "thresholds.too_close: expected a number, got the text '5'"),
        ("skeleton: {units: true}\n", "skeleton.units: "),
    ],
)  # fmt: skip
def test_yaml_types_are_kept(tmp_path: Path, extra: str, message: str) -> None:
    """`divisions: true` was read as 1 division (every sample snapped to the axis ends), and a
    quoted number or the text 'off' as a number or false: what the committed JSON Schema rejects,
    the loader accepted. An int is still a number (`min: -180`)."""
    error = load_error(tmp_path, MINIMAL + extra)
    assert error.message.startswith(message), error.message


def test_a_number_where_text_is_expected_hints_quotes(tmp_path: Path) -> None:
    error = load_error(tmp_path, "schema_version: 1\nname: 2024\nclips: [{path: a.bvh}]\n")
    assert where(error) == (2, 1)
    assert error.message == "name: expected text, got the number 2024"
    assert error.hint == 'quote it to make it text: "2024"'


def test_bad_literal_lists_allowed_values_and_suggests(tmp_path: Path) -> None:
    error = load_error(
        tmp_path, MINIMAL + "axes:\n  y:\n    feature: sped\n    min: -3\n    max: 6\n    divisions: 90\n"
    )
    assert where(error) == (7, 5)
    assert error.message == "axes.y.feature: unknown value 'sped'"
    assert error.hint is not None and error.hint.startswith("did you mean 'speed'? allowed values: speed, ")
    assert "turn_rate" in error.hint


def test_bad_expect_feature_points_at_the_key(tmp_path: Path) -> None:
    error = load_error(
        tmp_path, "schema_version: 1\nname: w\nclips:\n  - path: a.bvh\n    expect: {trun_rate: 0}\n"
    )
    assert where(error) == (5, 14)
    assert error.message == "clips[0].expect.trun_rate: unknown key 'trun_rate'"
    assert error.hint is not None and error.hint.startswith("did you mean 'turn_rate'?")


def test_units_accepts_a_name_or_a_positive_number(tmp_path: Path) -> None:
    error = load_error(tmp_path, MINIMAL + "skeleton:\n  units: cms\n")
    assert where(error) == (6, 3)
    assert error.message == (
        "skeleton.units: expected one of 'auto', 'm', 'cm', 'mm', 'in' or a number, got the text 'cms'"
    )
    assert error.hint is not None and error.hint.startswith("did you mean 'cm'?")
    negative = load_error(tmp_path, MINIMAL + "skeleton:\n  units: -2\n")
    assert "a number > 0, got the number -2" in negative.message


def test_partial_mirror_reports_only_the_missing_token(tmp_path: Path) -> None:
    error = load_error(tmp_path, MINIMAL + "skeleton:\n  mirror: {left: Left}\n")
    assert isinstance(error, ManifestProblemsError) and len(error.problems) == 1
    assert error.message == "skeleton.mirror.right: required key 'right' is missing"
    assert where(error) == (6, 3)
    assert error.hint is not None and error.hint.startswith("add `right:`")


def test_axis_min_not_below_max(tmp_path: Path) -> None:
    error = load_error(tmp_path, MINIMAL + "axes:\n  y: {feature: speed, min: 6, max: 6, divisions: 90}\n")
    assert where(error) == (6, 3)
    assert error.message == "axes.y: min 6 is not below max 6"
    assert error.hint is not None and "swap" in error.hint


def test_both_axes_on_one_feature(tmp_path: Path) -> None:
    error = load_error(tmp_path, MINIMAL + "axes:\n  x: {feature: speed, min: 0, max: 1, divisions: 10}\n")
    assert where(error) == (5, 1)
    assert error.message == "axes: both axes use the feature 'speed'"


@pytest.mark.parametrize(
    ("entry", "position", "message"),
    [
        ("{rule: too-close}", (6, 9), "clips[0].ignore[0].reason: required key 'reason' is missing"),
        ('{rule: too-close, reason: "  "}', (6, 27), "clips[0].ignore[0].reason: the reason is empty"),
    ],
)
def test_ignore_needs_a_reason(tmp_path: Path, entry: str, position: tuple[int, int], message: str) -> None:
    error = load_error(
        tmp_path, f"schema_version: 1\nname: w\nclips:\n  - path: a.bvh\n    ignore:\n      - {entry}\n"
    )
    assert error.message == message
    assert where(error) == position
    assert error.hint is not None and "reason" in error.hint


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("[2.5, 0.5]", "start 2.5 s is not before end 0.5 s"),
        ("[-1, 2]", "starts before 0 s (-1)"),
        ("[1]", "expected 2 values, got 1"),
        ("[0, 1, 2]", "expected 2 values, got 3"),
    ],
)
def test_range_errors(tmp_path: Path, value: str, message: str) -> None:
    error = load_error(tmp_path, f"schema_version: 1\nname: w\nclips:\n  - path: a.bvh\n    range: {value}\n")
    assert error.message == f"clips[0].range: {message}"
    assert where(error) == (5, 5)


def test_unsafe_name_and_empty_clip_list(tmp_path: Path) -> None:
    error = load_error(tmp_path, "schema_version: 1\nname: ../evil\nclips: []\n")
    assert isinstance(error, ManifestProblemsError)
    texts = [(p.line, p.text()) for p in error.problems]
    assert texts == [
        (2, "name: '../evil' cannot be used as a file name"),
        (3, "clips: needs at least 1 item, got 0"),
    ]


def test_layer_kind_typo_and_style_clip_typo(tmp_path: Path) -> None:
    error = load_error(
        tmp_path,
        MINIMAL
        + """\
layers:
  - {name: lateral, kind: bta, manifest: l.yaml}
  - name: drunk
    kind: style
    clips:
      - path: s.bvh
        rnage: [0, 1]
""",
    )
    assert isinstance(error, ManifestProblemsError)
    assert [(p.line, p.column, p.text()) for p in error.problems] == [
        (6, 21, "layers[0].kind: unknown kind 'bta'"),
        (11, 9, "layers[1].clips[0].rnage: unknown key 'rnage'"),
    ]
    assert error.problems[0].hint is not None and error.problems[0].hint.startswith("did you mean 'beta'?")


def test_every_problem_is_reported_with_its_own_position(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        """\
        schema_version: 1
        name: walk
        clips:
          - path: a.bvh
            rnage: [0, 1]
        axes:
          x: {feature: sped, min: -180, max: 180, divisions: 100}
        output: {formats: [json, pgn]}
        """,
    )
    with pytest.raises(ManifestProblemsError) as caught:
        load_manifest(path)
    error = caught.value
    assert [(p.line, p.column, p.text()) for p in error.problems] == [
        (5, 5, "clips[0].rnage: unknown key 'rnage'"),
        (7, 7, "axes.x.feature: unknown value 'sped'"),
        (8, 26, "output.formats[1]: unknown value 'pgn'"),
    ]
    # The message carries all of them; the rendered text gives each its own hint.
    assert f"{path}:8:26: output.formats[1]: unknown value 'pgn'" in error.message
    rendered = error.render().splitlines()
    assert rendered[0] == f"{path}:5:5: clips[0].rnage: unknown key 'rnage'"
    assert rendered[2] == f"{path}:7:7: axes.x.feature: unknown value 'sped'"
    assert rendered[5].strip().startswith("hint: did you mean 'png'?")


# --- YAML-level errors -------------------------------------------------------------------------------


@pytest.mark.parametrize("text", ["", "\n\n", "# just a comment\n"])
def test_empty_manifest_shows_a_minimal_one(tmp_path: Path, text: str) -> None:
    error = load_error(tmp_path, text)
    assert error.message == "manifest is empty"
    assert where(error) == (1, 1)
    assert error.hint is not None and "schema_version: 1" in error.hint and "clips:" in error.hint


def test_alias_bomb_fails_fast(tmp_path: Path) -> None:
    lines = [
        "schema_version: 1",
        "name: lol",
        'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]',
    ]
    for previous, name in zip("abcdefgh", "bcdefghi", strict=True):
        lines.append(f"{name}: &{name} [" + ", ".join([f"*{previous}"] * 9) + "]")
    lines.append("clips: *i")
    path = write(tmp_path, "\n".join(lines) + "\n")
    start = time.perf_counter()
    with pytest.raises(ManifestError) as caught:
        load_manifest(path)
    assert time.perf_counter() - start < 1.0
    assert caught.value.message == "the manifest expands to more than 100000 values"
    assert caught.value.line == 8  # `f:` is the first key whose expansion passes the limit
    assert caught.value.hint is not None and "alias" in caught.value.hint


def test_small_aliases_are_fine(tmp_path: Path) -> None:
    loaded = load_manifest(
        write(
            tmp_path,
            """\
        schema_version: 1
        name: walk
        clips:
          - &common {path: a.bvh, range: [0, 1]}
          - {path: b.bvh}
        layers:
          - {name: s, kind: style, clips: [*common]}
        """,
        )
    )
    assert loaded.model.layers[0].clips[0] == loaded.model.clips[0]  # type: ignore[union-attr]


def test_duplicate_key(tmp_path: Path) -> None:
    error = load_error(tmp_path, "schema_version: 1\nname: a\nclips: [{path: a.bvh}]\nname: b\n")
    assert where(error) == (4, 1)
    assert error.message == "duplicate key 'name' (the mapping starts on line 1)"
    assert error.hint is not None


def test_yaml_syntax_error_uses_the_parser_position(tmp_path: Path) -> None:
    error = load_error(tmp_path, "schema_version: 1\nname: a\nclips: [a.bvh, b.bvh\nfixes: {}\n")
    assert where(error) == (4, 6)
    assert error.message.startswith("invalid YAML: expected ',' or ']'")
    assert "starts at line 3, column 8" in error.message


def test_tab_indentation(tmp_path: Path) -> None:
    error = load_error(tmp_path, "schema_version: 1\nname: a\nclips:\n\t- path: a.bvh\n")
    assert where(error) == (4, 1)
    assert "'\\t'" in error.message


@pytest.mark.parametrize(
    ("text", "position", "message"),
    [
        ("name: a\nclips: []\n", (1, 1), "missing `schema_version`"),
        ("# a comment first\nname: a\n", (2, 1), "missing `schema_version`"),
        (
            "name: a\nschema_version: 2\n",
            (2, 1),
            "unsupported schema_version 2: this blendspace-pipeline reads version 1",
        ),
        ('schema_version: "1"\n', (1, 1), "schema_version is the text '1', not the number 1"),
        (
            "schema_version: true\n",
            (1, 1),
            "unsupported schema_version true: this blendspace-pipeline reads version 1",  # YAML's word
        ),
    ],
)
def test_schema_version(tmp_path: Path, text: str, position: tuple[int, int], message: str) -> None:
    error = load_error(tmp_path, text)
    assert (where(error), error.message) == (position, message)
    assert error.hint is not None and "schema_version: 1" in error.hint


@pytest.mark.parametrize(("text", "kind"), [("- a.bvh\n", "a list"), ("just text\n", "a string")])
def test_top_level_must_be_a_mapping(tmp_path: Path, text: str, kind: str) -> None:
    error = load_error(tmp_path, text)
    assert error.message == f"the manifest's top level is {kind}, not a mapping of keys"
    assert where(error) == (1, 1)


def test_missing_manifest_suggests_a_near_name(tmp_path: Path) -> None:
    write(tmp_path, MINIMAL, "locomotion.yaml")
    with pytest.raises(ManifestError) as caught:
        load_manifest(tmp_path / "locomotoin.yaml")
    assert caught.value.message == "manifest not found"
    assert caught.value.hint == f"did you mean {str(tmp_path / 'locomotion.yaml')!r}?"


def test_manifest_that_is_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "manifest.yaml"
    path.write_bytes(b"schema_version: 1\nname: caf\xe9\n")
    with pytest.raises(ManifestError) as caught:
        load_manifest(path)
    assert (caught.value.line, caught.value.column) == (2, 10)
    assert "not UTF-8" in caught.value.message


def test_folder_instead_of_manifest(tmp_path: Path) -> None:
    with pytest.raises(ManifestError, match="folder, not a manifest"):
        load_manifest(tmp_path)


# --- locate -------------------------------------------------------------------------------------------


def test_locate_nested_paths_and_fallback(tmp_path: Path) -> None:
    loaded = load_manifest(write(tmp_path, SPEC_EXAMPLE))
    assert loaded.locate(("clips",)) == (3, 1)
    assert loaded.locate(("clips", 0)) == (4, 5)
    assert loaded.locate(("clips", 1)) == (5, 5)
    assert loaded.locate(("clips", 1, "range")) == (7, 5)
    assert loaded.locate(("clips", 1, "range", 1)) == (7, 18)
    assert loaded.locate(("clips", 1, "ignore", 0, "reason")) == (10, 32)
    assert loaded.locate(("axes", "y", "divisions")) == (20, 40)
    # Absent keys and indices fall back to the nearest existing parent.
    assert loaded.locate(("clips", 0, "range")) == (4, 5)
    assert loaded.locate(("clips", 7)) == (3, 1)
    assert loaded.locate(("nothing", "here")) == (1, 1)
    assert loaded.locate(()) == (1, 1)
    assert loaded.directory == tmp_path


# --- clip path resolution ------------------------------------------------------------------------------


def load_clips(folder: Path, clips_yaml: str) -> LoadedManifest:
    """A manifest whose `clips:` block is ``clips_yaml``; its entries start on line 4."""
    return load_manifest(write(folder, f"schema_version: 1\nname: t\nclips:\n{clips_yaml}"))


def resolve(folder: Path, clips_yaml: str) -> list[Path]:
    return [r.path for r in resolve_clip_files(load_clips(folder, clips_yaml))]


def test_glob_is_sorted_and_skips_folders_and_non_clips(tmp_path: Path) -> None:
    touch(tmp_path, "clips/walk.bvh", "clips/Run.bvh", "clips/idle.bvh", "clips/notes.md", "clips/b.glb")
    (tmp_path / "clips" / "folder.bvh").mkdir()
    files = resolve(tmp_path, "  - path: clips/*\n")
    assert [f.name for f in files] == ["Run.bvh", "b.glb", "idle.bvh", "walk.bvh"]
    assert all(f.is_absolute() for f in files)


@pytest.mark.parametrize("pattern", ["*.bvh", "*", ".*", "[wR]*.bvh", "?alk.bvh", "*.BVH"])
def test_a_one_folder_glob_matches_what_glob_matches(tmp_path: Path, pattern: str) -> None:
    """The listing fast path (`_folder_files`: no stat per file) answers as `glob.glob` does:
    hidden names only for a pattern starting with a dot, folders and dangling links left out,
    links to files followed, case as the system compares names."""
    import glob
    import os

    touch(
        tmp_path, "clips/walk.bvh", "clips/Run.bvh", "clips/.hidden.bvh", "clips/notes.md", "target/far.bvh"
    )
    folder = tmp_path / "clips"
    (folder / "folder.bvh").mkdir()
    os.symlink(tmp_path / "target" / "far.bvh", folder / "linked.bvh")
    os.symlink(tmp_path / "nowhere.bvh", folder / "dangling.bvh")
    expected = sorted(
        os.path.normpath(folder / name)
        for name in glob.glob(pattern, root_dir=folder)
        if os.path.isfile(folder / name) and Path(name).suffix.lower() in {".bvh"}
    )
    loaded = load_clips(tmp_path, f"  - path: 'clips/{pattern}'\n")
    try:
        found = [str(r.path) for r in resolve_clip_files(loaded)]
    except ManifestError:
        found = []  # matched no clip: an error naming the entry (tested elsewhere)
    assert sorted(found) == expected


def test_windows_backslashes_work_on_posix(tmp_path: Path) -> None:
    touch(tmp_path, "clips/walk.bvh", "clips/sub/run.bvh")
    files = resolve(tmp_path, "  - path: 'clips\\walk.bvh'\n  - path: clips\\sub\\*.bvh\n")
    assert files == [tmp_path / "clips" / "walk.bvh", tmp_path / "clips" / "sub" / "run.bvh"]


def test_dotdot_absolute_and_recursive_paths(tmp_path: Path) -> None:
    touch(tmp_path, "shared/walk.bvh", "shared/deep/er/run.bvh", "elsewhere/idle.bvh")
    project = tmp_path / "project"
    files = resolve(
        project,
        f"""\
  - path: ../shared/walk.bvh
  - path: ../shared/**/*.bvh
  - path: {tmp_path / "elsewhere" / "idle.bvh"}
  - path: {tmp_path / "elsew*" / "*.bvh"}
""",
    )
    assert files == [
        tmp_path / "shared" / "walk.bvh",
        tmp_path / "shared" / "deep" / "er" / "run.bvh",
        tmp_path / "elsewhere" / "idle.bvh",
    ]


def test_brackets_in_folder_and_file_names(tmp_path: Path) -> None:
    project = tmp_path / "take[1]"
    touch(project, "clips/walk[2].bvh", "clips/run.bvh")
    files = resolve(project, "  - path: clips/walk[2].bvh\n  - path: clips/r*.bvh\n")
    assert files == [project / "clips" / "walk[2].bvh", project / "clips" / "run.bvh"]


def test_a_file_matched_twice_belongs_to_the_explicit_entry(tmp_path: Path) -> None:
    touch(tmp_path, "clips/a.bvh", "clips/b.bvh", "clips/c.bvh")
    loaded = load_clips(
        tmp_path,
        """\
  - path: clips/*.bvh
  - path: clips/?.bvh
  - path: clips/./b.bvh
    name: bee
""",
    )
    resolved = [
        (r.path.name, r.entry_index, r.line, r.column, r.entry.name) for r in resolve_clip_files(loaded)
    ]
    assert resolved == [("a.bvh", 0, 4, 5, None), ("c.bvh", 0, 4, 5, None), ("b.bvh", 2, 6, 5, "bee")]


def test_a_symlink_and_its_target_are_one_clip(tmp_path: Path) -> None:
    """A file reached through a linked file or a linked folder is the file it links to: listed
    explicitly, it belongs to that entry; only the glob's spelling of it is dropped."""
    touch(tmp_path, "clips/a.bvh", "clips/b.bvh")
    (tmp_path / "alias.bvh").symlink_to(tmp_path / "clips" / "a.bvh")
    (tmp_path / "mirror").symlink_to(tmp_path / "clips", target_is_directory=True)
    loaded = load_clips(tmp_path, "  - path: clips/*.bvh\n  - path: alias.bvh\n  - path: mirror/b.bvh\n")
    resolved = [(r.path.relative_to(tmp_path).as_posix(), r.entry_index) for r in resolve_clip_files(loaded)]
    assert resolved == [("alias.bvh", 1), ("mirror/b.bvh", 2)]
    loaded = load_clips(tmp_path, "  - path: clips/*.bvh\n  - path: mirror/*.bvh\n")
    resolved = [(r.path.relative_to(tmp_path).as_posix(), r.entry_index) for r in resolve_clip_files(loaded)]
    assert resolved == [("clips/a.bvh", 0), ("clips/b.bvh", 0)]


def test_glob_that_matches_nothing_points_at_its_entry(tmp_path: Path) -> None:
    touch(tmp_path, "clips/walk.bvh")
    loaded = load_clips(tmp_path, "  - path: clips/walk.bvh\n  - {name: x, path: mocap/*.bvh}\n")
    with pytest.raises(ManifestError) as caught:
        resolve_clip_files(loaded)
    assert where(caught.value) == (5, 15)
    assert caught.value.message == "glob 'mocap/*.bvh' matched no files"
    assert caught.value.hint == f"the folder {tmp_path / 'mocap'} does not exist"

    touch(tmp_path, "mocap/readme.txt")
    with pytest.raises(ManifestError) as caught:
        resolve_clip_files(loaded)
    assert caught.value.hint is not None and caught.value.hint.startswith(f"looked in {tmp_path / 'mocap'}")


def test_glob_of_unreadable_files_says_so(tmp_path: Path) -> None:
    touch(tmp_path, "maya/walk.ma")  # Maya scenes need Maya (FBX is readable with the fbx extra)
    loaded = load_clips(tmp_path, "  - path: maya/*\n")
    with pytest.raises(ManifestError) as caught:
        resolve_clip_files(loaded)
    assert caught.value.message == "glob 'maya/*' matched no readable clip files"
    assert caught.value.hint is not None and "walk.ma" in caught.value.hint and ".bvh" in caught.value.hint


def test_missing_file_suggests_near_names(tmp_path: Path) -> None:
    touch(tmp_path, "clips/walk_fwd.bvh", "clips/run_fwd.bvh")
    loaded = load_clips(tmp_path, "  - path: clips/run_fwd.bvh\n  - path: clips/wlak_fwd.bvh\n")
    with pytest.raises(ManifestError) as caught:
        resolve_clip_files(loaded)
    assert where(caught.value) == (5, 5)
    assert caught.value.message == "clip file 'clips/wlak_fwd.bvh' not found"
    assert (
        caught.value.hint == f"did you mean 'walk_fwd.bvh' or 'run_fwd.bvh'? (looked in {tmp_path / 'clips'})"
    )


def test_missing_file_in_another_letter_case_names_the_file(tmp_path: Path) -> None:
    """A manifest written on Windows (`Clips/Walk_Bwd.bvh`) fails on Linux CI: the folder does not
    exist in that case, and the hint said only "the folder does not exist"."""
    touch(tmp_path, "clips/walk_bwd.bvh", "clips/walk_fwd.bvh")
    if (tmp_path / "CLIPS").exists():
        pytest.skip("a case-insensitive file system: the file is found")
    loaded = load_clips(tmp_path, "  - path: Clips/Walk_Bwd.bvh\n")
    with pytest.raises(ManifestError) as caught:
        resolve_clip_files(loaded)
    assert caught.value.message == "clip file 'Clips/Walk_Bwd.bvh' not found"
    assert caught.value.hint is not None
    assert caught.value.hint.startswith(
        "did you mean 'clips/walk_bwd.bvh'? The names differ in letter case only"
    )


def test_folder_given_as_a_clip_and_named_glob_of_many(tmp_path: Path) -> None:
    touch(tmp_path, "clips/a.bvh", "clips/b.bvh")
    loaded = load_clips(tmp_path, "  - path: clips\n")
    with pytest.raises(ManifestError, match="'clips' is a folder, not a clip file"):
        resolve_clip_files(loaded)
    loaded = load_clips(tmp_path, "  - path: clips/*.bvh\n    name: walk\n")
    with pytest.raises(ManifestError) as caught:
        resolve_clip_files(loaded)
    assert caught.value.message == "the entry is named 'walk' but its glob 'clips/*.bvh' matched 2 files"
    assert where(caught.value) == (4, 5)


def test_a_named_glob_of_one_file_is_fine(tmp_path: Path) -> None:
    touch(tmp_path, "clips/a.bvh")
    files = resolve(tmp_path, "  - {path: clips/*.bvh, name: walk}\n")
    assert files == [tmp_path / "clips" / "a.bvh"]


def test_style_layer_clips_resolve_with_their_own_lines(tmp_path: Path) -> None:
    touch(tmp_path, "walk.bvh", "styles/drunk.bvh")
    loaded = load_manifest(
        write(tmp_path, MINIMAL + "layers:\n  - name: d\n    kind: style\n    clips:\n      - styles/*.bvh\n")
    )
    layer = loaded.model.layers[0]
    assert isinstance(layer, StyleLayer)
    entries = [c if isinstance(c, ClipEntry) else ClipEntry(path=c) for c in layer.clips]
    resolved = resolve_clip_files(loaded, entries=entries, key=("layers", 0, "clips"))
    assert [(r.path, r.line, r.column) for r in resolved] == [(tmp_path / "styles" / "drunk.bvh", 9, 9)]


def test_spec_example_resolves(tmp_path: Path) -> None:
    touch(tmp_path, "clips/walk_fwd.bvh", "clips/idle.bvh", "mocap/run_fwd.bvh")
    loaded = load_manifest(write(tmp_path, SPEC_EXAMPLE))
    resolved = resolve_clip_files(loaded)
    assert [(r.path.relative_to(tmp_path).as_posix(), r.entry_index) for r in resolved] == [
        ("clips/idle.bvh", 0),
        ("clips/walk_fwd.bvh", 0),
        ("mocap/run_fwd.bvh", 1),
    ]


# --- command line -------------------------------------------------------------------------------------


def test_schema_command_prints_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema", "manifest"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert schema["additionalProperties"] is False
    assert schema["required"] == ["schema_version", "name", "clips"]
    assert schema["properties"]["clips"]["description"]
    assert main(["schema"]) == 0
    assert json.loads(capsys.readouterr().out) == schema
    assert main(["schema", "blendspace"]) == 0
    assert "samples" in json.loads(capsys.readouterr().out)["properties"]


def test_cli_reports_manifest_errors_with_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, MINIMAL + "axes: {x: {feature: sped, min: 0, max: 1, divisions: 1}}\n")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}:5:12: axes.x.feature: unknown value 'sped'" in err
    assert "hint: did you mean 'speed'?" in err
    assert "Traceback" not in err


def test_glob_over_the_shared_cmu_folder_skips_its_notes(tmp_path: Path) -> None:
    folder = SHARED_DATA / "cmu"
    if not folder.is_dir():
        pytest.skip(f"{folder} is not present (the shared data folder sits beside the repository)")
    files = resolve(tmp_path, f"  - path: {folder.as_posix()}/*\n")
    assert files == sorted(folder.glob("*.bvh"))
    assert files and all(f.suffix == ".bvh" for f in files)


def test_a_hand_position_outside_the_axes_is_an_error(tmp_path: Path) -> None:
    error = load_error(
        tmp_path,
        "schema_version: 1\nname: w\nclips:\n  - path: a.bvh\n  - path: b.bvh\n    position: [0, 99]\n",
    )
    assert error.message == "clips[1].position: 99 is outside the y axis (speed) range [-3, 6]"
    assert where(error) == (6, 5)
    assert error.hint is not None and "axis" in error.hint


@pytest.mark.parametrize("name", ["walk\\0", "walk\\a", "walk\\r", "walk\\u202e", "walk\\x85"])
def test_a_clip_name_with_a_control_character_is_refused_at_its_line(tmp_path: Path, name: str) -> None:
    """A name goes into every output and engine asset: a NUL, a bell, a carriage return or a
    bidirectional override there is an error at the manifest's line, not a byte in a .tres."""
    touch(tmp_path, "clips/walk.bvh")
    error = load_error(
        tmp_path, f'schema_version: 1\nname: t\nclips:\n  - path: clips/walk.bvh\n    name: "{name}"\n'
    )
    assert error.line == 5 and "control character" in error.message


def test_a_control_character_in_the_yaml_is_named_at_its_line_and_column(tmp_path: Path) -> None:
    """`printf "dir: 'C:\\build'"` writes a raw backspace: the error gave a character offset and a
    literal `\\n` instead of `path:line:column`."""
    error = load_error(
        tmp_path, "schema_version: 1\nname: t\nclips:\n  - path: a.bvh\noutput: {dir: 'C:\x08uild'}\n"
    )
    assert (error.line, error.column) == (5, 18)
    assert "U+0008" in error.message and "\\n" not in error.message


def test_a_windows_drive_output_folder_is_refused_where_there_are_no_drives(tmp_path: Path) -> None:
    """`output.dir: 'C:\\build'` made a folder named `C:` beside the manifest on Linux."""
    if os.name == "nt":
        pytest.skip("drives exist here")
    error = load_error(
        tmp_path, "schema_version: 1\nname: t\nclips:\n  - path: a.bvh\noutput: {dir: 'C:/build'}\n"
    )
    assert error.line == 5 and "Windows drive path" in error.message


def test_a_home_output_folder_is_the_home_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`output.dir: ~/out` made a folder literally named `~`."""
    from blendspace_pipeline.pipeline.own_outputs import output_folder

    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    touch(tmp_path, "a.bvh")
    loaded = load_manifest(
        write(tmp_path, "schema_version: 1\nname: t\nclips:\n  - path: a.bvh\noutput: {dir: ~/out}\n")
    )
    assert output_folder(loaded, None) == tmp_path / "home" / "out"


@pytest.mark.parametrize("name", ["''", "'a=b'", "'  '"])
def test_a_layer_name_eval_cannot_reach_is_refused(tmp_path: Path, name: str) -> None:
    """Layer names `''` and `a=b` built, but `eval --layer NAME=VALUE` could never give them."""
    touch(tmp_path, "a.bvh", "s.bvh")
    error = load_error(
        tmp_path,
        "schema_version: 1\nname: t\nclips:\n  - path: a.bvh\n"
        f"layers:\n  - name: {name}\n    kind: style\n    clips: [s.bvh]\n",
    )
    assert error.line == 6 and "layer name" in error.message


@pytest.mark.parametrize(
    "key", ["position: [0, 1]", "expect: {speed: 1}", "ignore: [{rule: not-a-rule, reason: x}]"]
)
def test_a_style_clip_entry_refuses_the_keys_that_do_nothing_there(tmp_path: Path, key: str) -> None:
    """A style clip sits at its measured speed: `position:`, `expect:` and `ignore:` did nothing on
    its entry, with no word (even an unknown rule in `ignore:`)."""
    touch(tmp_path, "a.bvh", "s.bvh")
    error = load_error(
        tmp_path,
        "schema_version: 1\nname: t\nclips:\n  - path: a.bvh\n"
        f"layers:\n  - name: limp\n    kind: style\n    clips:\n      - path: s.bvh\n        {key}\n",
    )
    assert "a style clip takes no" in error.message and error.line is not None
