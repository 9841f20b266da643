"""`blendspace index` on a local Dask cluster and `blendspace suggest`: the suggested library
clips really fill the placeholders (rebuilding with them removes the findings)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.pipeline.library import read_index
from blendspace_pipeline.writers.bvh import write_bvh_clip

MANIFEST_CLIPS = [
    GaitSpec("idle", duration=1.0),
    GaitSpec("walk", speed=1.4, duration=1.0),
    GaitSpec("run", speed=4.0, duration=1.0),
    GaitSpec("walk_left", speed=1.4, turn_rate=60.0, duration=1.0),  # its mirror is missing
]
LIBRARY_CLIPS = [
    GaitSpec("take_walk_right", speed=1.4, turn_rate=-60.0, duration=1.0),  # fills the placeholder
    GaitSpec("take_run_right", speed=4.0, turn_rate=-120.0, duration=1.0),
    GaitSpec("take_jog", speed=2.5, duration=1.0),
]


def _write(folder: Path, specs: list[GaitSpec]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for spec in specs:
        write_bvh_clip(generate(spec), folder / f"{spec.name}.bvh")


def test_index_and_suggest_fill_the_placeholders(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _write(tmp_path / "project" / "clips", MANIFEST_CLIPS)
    _write(tmp_path / "library" / "day1", LIBRARY_CLIPS[:2])
    _write(tmp_path / "library" / "day2", LIBRARY_CLIPS[2:])
    (tmp_path / "library" / "notes.txt").write_text("not a clip", encoding="utf-8")
    manifest = tmp_path / "project" / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    before = analyse(manifest)
    assert [d.rule for d in before.diagnostics if d.rule == "missing-opposite"] == ["missing-opposite"]
    assert before.placeholders

    store = str(tmp_path / "store")
    assert main(["index", str(tmp_path / "library"), "--store", store, "--workers", "1"]) == 0
    assert "indexed 3 animation(s) from 3 file(s)" in capsys.readouterr().out
    rows = read_index(store)
    assert sorted(r["name"] for r in rows) == sorted(s.name for s in LIBRARY_CLIPS)
    by_name = {r["name"]: r for r in rows}
    # The measured features are the generator's truth.
    assert by_name["take_walk_right"]["feature.turn_rate"] == pytest.approx(-60.0, abs=0.5)
    assert by_name["take_walk_right"]["feature.speed"] == pytest.approx(1.4, abs=0.05)
    assert len(list((tmp_path / "store" / "clips").glob("*.json"))) == 3

    assert main(["suggest", str(manifest), "--library", store, "--format", "json"]) == 0
    result = json.loads(capsys.readouterr().out)
    mirror = next(p for p in result["placeholders"] if p["rule"] == "missing-opposite")
    assert mirror["candidates"][0]["name"] == "take_walk_right" and mirror["candidates"][0]["fills"]
    # The three library takes cannot fill every placeholder (e.g. the coverage ones): those are
    # listed with their nearest clips, none marked as filling.
    unfilled = [p for p in result["placeholders"] if not any(c["fills"] for c in p["candidates"])]
    assert unfilled and all(p["rule"] != "missing-opposite" for p in unfilled)
    assert "take_walk_right.bvh" in result["patch"] and "take_run_right" not in result["patch"]

    # Apply the patch: the finding and its placeholder go away.
    patched = manifest.read_text(encoding="utf-8") + "".join(
        f"  {line}\n" for line in result["patch"].splitlines()
    )
    manifest.write_text(patched, encoding="utf-8")
    after = analyse(manifest)
    assert not [d for d in after.diagnostics if "walk_left" in d.clips and d.rule == "missing-opposite"]
    # Every placeholder of the first build that got a candidate is filled: none is left there.
    filled = [
        p["position"] for p in result["placeholders"] if p["candidates"] and p["candidates"][0]["fills"]
    ]
    assert filled
    remaining = [list(p.position) for p in after.placeholders]
    for position in filled:
        assert all(abs(x - position[0]) > 1e-6 or abs(y - position[1]) > 1e-6 for x, y in remaining)

    # Indexing again measures nothing new: the store already holds every file's bytes.
    assert main(["index", str(tmp_path / "library"), "--store", store, "--workers", "1"]) == 0
    assert len(list((tmp_path / "store" / "clips").glob("*.json"))) == 3
    capsys.readouterr()
    assert main(["suggest", str(manifest), "--library", store]) == 0
    assert "placeholder(s)" in capsys.readouterr().out


def test_index_rejects_a_missing_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["index", str(tmp_path / "nope"), "--store", str(tmp_path / "s")]) == 2
    assert "not a folder" in capsys.readouterr().err


def test_index_runs_on_a_given_scheduler(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """DASK_SCHEDULER_ADDRESS (a studio's cluster; here one started by the test) takes the job
    instead of an embedded cluster, and `--scheduler` does the same."""
    from distributed import LocalCluster

    _write(tmp_path / "library", LIBRARY_CLIPS[:2])
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", cluster.scheduler_address)
        assert main(["index", str(tmp_path / "library"), "--store", str(tmp_path / "a")]) == 0
        monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")
        store = str(tmp_path / "b")
        argv = [
            "index",
            str(tmp_path / "library"),
            "--store",
            store,
            "--scheduler",
            cluster.scheduler_address,
        ]
        assert main(argv) == 0
        # The cluster still runs: index closed its client, not the studio's scheduler.
        assert cluster.scheduler is not None and cluster.status.name == "running"
    assert sorted(r["name"] for r in read_index(str(tmp_path / "a"))) == ["take_run_right", "take_walk_right"]
    assert sorted(r["name"] for r in read_index(store)) == ["take_run_right", "take_walk_right"]
    assert capsys.readouterr().out.count("indexed 2 animation(s)") == 2
