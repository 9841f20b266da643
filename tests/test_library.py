"""`blendspace index` on a local Dask cluster and `blendspace suggest`: the suggested library
clips really fill the placeholders (rebuilding with them removes the findings)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.pipeline.library import read_index, write_index
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


def _project(tmp_path: Path) -> Path:
    """The gait project of the first test (its placeholders need a library), not yet patched."""
    _write(tmp_path / "project" / "clips", MANIFEST_CLIPS)
    manifest = tmp_path / "project" / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    return manifest


def _damaged_index(tmp_path: Path) -> str:
    (tmp_path / "damaged").mkdir()
    (tmp_path / "damaged" / "index.parquet").write_bytes(b"not parquet")
    return str(tmp_path / "damaged")


def _foreign_parquet(tmp_path: Path) -> str:
    import pyarrow as pa
    import pyarrow.parquet as pq

    (tmp_path / "foreign").mkdir()
    pq.write_table(pa.table({"sales": [1, 2]}), tmp_path / "foreign" / "index.parquet")
    return str(tmp_path / "foreign")


def _junk_file(tmp_path: Path) -> str:
    (tmp_path / "junk.bin").write_bytes(b"\x00junk")
    return str(tmp_path / "junk.bin")


# Stores that are not an index, and what suggest must say about each (after "STORE: ").
NOT_AN_INDEX: dict[str, tuple[Callable[[Path], str], str]] = {
    "missing-folder": (lambda tmp_path: str(tmp_path / "no-such-store"), "the library store does not exist"),
    # The existence test goes through fsspec, so a URL is judged like a folder (os.path would not).
    "missing-url": (lambda tmp_path: f"memory://{tmp_path.name}/none", "the library store does not exist"),
    "junk-file": (_junk_file, "not a blendspace index (a file, not the folder `blendspace index` writes)"),
    "project-folder": (
        lambda tmp_path: str(tmp_path / "project"),
        "not a blendspace index (no index.parquet)",
    ),
    "damaged-index": (_damaged_index, "index.parquet cannot be read: "),
    "foreign-parquet": (_foreign_parquet, "not a blendspace index (index.parquet has no digest, name, path"),
    # The same words as `build --library` gives for a store fsspec cannot open (store_problem).
    "unknown-protocol": (lambda tmp_path: "nosuchprotocol://store", "the library store cannot be opened: "),
}


@pytest.mark.parametrize("kind", NOT_AN_INDEX)
@pytest.mark.parametrize("output", ["text", "json"])
def test_suggest_rejects_a_store_that_is_not_an_index(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str, output: str
) -> None:
    """A typo in a CI variable must be bad input (exit 2) naming the store, not an empty library
    ("no library clip of this skeleton" under every placeholder, exit 0)."""
    manifest = _project(tmp_path)
    make_store, problem = NOT_AN_INDEX[kind]
    store = make_store(tmp_path)
    assert main(["suggest", str(manifest), "--library", store, "--format", output]) == 2
    printed = capsys.readouterr()
    assert printed.out == ""
    first, hint = printed.err.splitlines()[:2]
    assert first.startswith(f"{store}: {problem}")
    assert hint.startswith("    hint: ")
    if kind != "unknown-protocol":
        assert f"blendspace index LIBRARY_DIR --store {store}" in hint
    assert "Traceback" not in printed.err


def test_suggest_reads_the_index_of_an_empty_library(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An index of a folder with no clips is a valid index with no rows: nothing fits, exit 0."""
    manifest = _project(tmp_path)
    (tmp_path / "empty-library").mkdir()
    store = str(tmp_path / "store")
    assert main(["index", str(tmp_path / "empty-library"), "--store", store, "--workers", "1"]) == 0
    assert "indexed 0 animation(s)" in capsys.readouterr().out
    assert main(["suggest", str(manifest), "--library", store]) == 0
    out = capsys.readouterr().out
    assert "placeholder(s), 0 library clip(s) of its skeleton" in out
    assert "no library clip of this skeleton" in out


def test_suggest_reads_an_index_at_an_fsspec_url(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A store is any fsspec location: an (empty) index in fsspec's in-memory filesystem is found."""
    import fsspec

    manifest = _project(tmp_path)
    store = f"memory://{tmp_path.name}/store"
    write_index(store, [])
    try:
        assert main(["suggest", str(manifest), "--library", store, "--format", "json"]) == 0
    finally:
        fsspec.filesystem("memory").rm(f"/{tmp_path.name}", recursive=True)
    result = json.loads(capsys.readouterr().out)
    assert result["placeholders"] and all(not p["candidates"] for p in result["placeholders"])


@pytest.mark.parametrize("count", ["0", "-1"])
def test_suggest_rejects_a_count_below_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], count: str
) -> None:
    """--count 0 listed no candidate and said "no library clip" under every placeholder, and -1
    dropped the last of each ranking: both are usage errors (exit 2) naming the option."""
    manifest = _project(tmp_path)
    store = str(tmp_path / "store")
    write_index(store, [])
    assert main(["suggest", str(manifest), "--library", store, "--count", count]) == 2
    printed = capsys.readouterr()
    assert printed.out == ""
    assert f"argument --count: {count} is not a positive number of candidates" in printed.err


def test_suggest_leaves_out_library_clips_of_another_hierarchy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A take with the set's joint names under other parents (or in another order) cannot be
    blended with it (`inconsistent-skeleton`): it is not proposed, however near it lies. A store
    indexed before the hierarchy was recorded still matches by joint names."""
    from blendspace_pipeline.motion.hostile import on_other_skeleton

    _write(tmp_path / "project" / "clips", MANIFEST_CLIPS)
    library = tmp_path / "library"
    library.mkdir()
    for change in ("reparented", "reordered"):  # exactly where the mirror of walk_left goes
        clip = on_other_skeleton(
            generate(GaitSpec(f"take_{change}", speed=1.4, turn_rate=-60.0, duration=1.0)), change
        )
        write_bvh_clip(clip, library / f"take_{change}.bvh")
    write_bvh_clip(
        generate(GaitSpec("take_near", speed=1.4, turn_rate=-57.0, duration=1.0)), library / "take_near.bvh"
    )
    manifest = tmp_path / "project" / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    store = str(tmp_path / "store")
    assert main(["index", str(library), "--store", store, "--workers", "1"]) == 0
    capsys.readouterr()

    def mirror_candidates() -> list[str]:
        assert main(["suggest", str(manifest), "--library", store, "--format", "json"]) == 0
        result = json.loads(capsys.readouterr().out)
        mirror = next(p for p in result["placeholders"] if p["rule"] == "missing-opposite")
        return [c["name"] for c in mirror["candidates"]]

    assert mirror_candidates() == ["take_near"]
    # An older store: rows without `layout`, matched by names (the reordered take has them all).
    rows = [{k: v for k, v in row.items() if k != "layout"} for row in read_index(store)]
    write_index(store, rows)
    assert sorted(mirror_candidates()) == ["take_near", "take_reordered", "take_reparented"]


def test_suggest_proposes_no_copy_of_the_projects_clips_and_its_patch_loads(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A library that holds copies of the project's takes had them proposed (same bytes), and the
    patch named them by absolute path with no `name:`: the patched manifest then failed ("two
    clips are named 'idle'"). A library take named like a project clip gets a `name:` now."""
    _write(tmp_path / "project" / "clips", MANIFEST_CLIPS)
    _write(tmp_path / "library", MANIFEST_CLIPS)  # the same bytes
    # The mirror the project misses, under a name the project uses already.
    (tmp_path / "library" / "extra").mkdir()
    write_bvh_clip(generate(LIBRARY_CLIPS[0]), tmp_path / "library" / "extra" / "walk.bvh")
    manifest = tmp_path / "project" / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: gait\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    store = str(tmp_path / "store")
    assert main(["index", str(tmp_path / "library"), "--store", store, "--workers", "1"]) == 0
    capsys.readouterr()
    assert main(["suggest", str(manifest), "--library", store, "--format", "json"]) == 0
    result = json.loads(capsys.readouterr().out)
    proposed = {c["path"] for p in result["placeholders"] for c in p["candidates"]}
    assert proposed == {str(tmp_path / "library" / "extra" / "walk.bvh")}
    assert result["patch"] == '- path: "../library/extra/walk.bvh"\n  name: "walk_library"\n'
    manifest.write_text(
        manifest.read_text(encoding="utf-8")
        + "".join(f"  {line}\n" for line in result["patch"].splitlines()),
        encoding="utf-8",
    )
    names = [s.name for s in analyse(manifest).samples if not s.generated]
    assert sorted(names) == sorted([*(s.name for s in MANIFEST_CLIPS), "walk_library"])
