"""The Python entry point agrees with the command line it stands beside."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.scripting import build, check, evaluate

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def sample(tmp_path: Path) -> Path:
    """A copy of the sample project (the build writes into its folder)."""
    copy = tmp_path / "sample"
    shutil.copytree(REPO / "sample_project", copy, ignore=shutil.ignore_patterns("build"))
    return copy / "manifest.yaml"


def test_check_returns_the_cli_findings_and_exit_code(
    sample: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    result = check(sample)
    code = main(["check", str(sample), "--format", "json"])
    printed = json.loads(capsys.readouterr().out)
    assert result.exit_code == code
    assert sorted((d.rule, tuple(d.clips)) for d in result.diagnostics) == sorted(
        (d["rule"], tuple(d["clips"])) for d in printed["diagnostics"]
    )
    assert not (sample.parent / "build").exists(), "check writes nothing"
    strict = check(sample, strict=True)
    assert strict.exit_code == (1 if any(d.severity != "info" for d in strict.diagnostics) else 0)


def test_build_writes_and_evaluate_reads_the_document(sample: Path) -> None:
    result = build(sample)
    assert result.document_path is not None and result.document_path.is_file()
    assert all(path.exists() for path in result.outputs)
    assert result.generated  # the sample is a flawed draft: the fixes bake clips
    doc = json.loads(result.document_path.read_text(encoding="utf-8"))
    first = doc["samples"][0]["position"]
    weights = evaluate(result.document_path, first[0], first[1])
    assert sum(w.weight for w in weights.weights) == pytest.approx(1.0)
    assert weights.weights[0].clip == doc["samples"][0]["name"]


def test_bad_input_raises_input_error_with_a_location(tmp_path: Path) -> None:
    manifest = tmp_path / "typo.yaml"
    manifest.write_text("schema_version: 1\nname: x\nclip: []\n", encoding="utf-8")
    with pytest.raises(InputError) as caught:
        check(manifest)
    error = caught.value
    assert Path(str(error.path)) == manifest and error.line is not None
    assert "unknown key 'clip'" in str(error)
    with pytest.raises(InputError):
        check(tmp_path / "typo.yaml", jobs=0)


def test_importing_the_entry_point_loads_no_heavy_module() -> None:
    import subprocess
    import sys

    code = "import sys, blendspace_pipeline.scripting; print(sorted(sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    for heavy in ("pxr", "OpenImageIO", "scipy"):
        assert f"'{heavy}'" not in out, heavy
