"""Faults while publishing outputs: kill -9 in the middle of writing, a full disk (a real
size-limited tmpfs where the machine allows mounting one, and an injected ENOSPC / a library that
says yes to a truncated PNG), and a failed rename. In every case a reader sees the previous build's
complete set (or the new one), never a mix, and the next build cleans up."""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.pipeline import outputs
from blendspace_pipeline.writers.usd_clip import write_usd_clip

NAMES = ("t.blendspace.json", "t.blendspace.usda", "t.report.html", "t.png")


@pytest.fixture(autouse=True)
def _isolated(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "user-cache"))


def _project(root: Path, divisions: int = 100, *, run: bool = False) -> Path:
    """Idle, walk and turn (and with ``run`` a 3.5 m/s run) as USD clips, and their manifest."""
    clips = root / "clips"
    clips.mkdir(parents=True, exist_ok=True)
    specs = {"idle": GaitSpec("idle"), "walk": GaitSpec("walk", speed=1.4)}
    if run:
        specs["run"] = GaitSpec("run", speed=3.5)
    specs["turn"] = GaitSpec("turn", turn_rate=90.0)
    for name, spec in specs.items():
        if not (clips / f"{name}.usda").exists():
            write_usd_clip(generate(spec), clips / f"{name}.usda", meters_per_unit=1.0, up_axis="y")
    manifest = root / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nclips:\n  - path: clips/*.usda\n"
        f"axes:\n  x: {{feature: turn_rate, min: -180, max: 180, divisions: {divisions}}}\n",
        encoding="utf-8",
    )
    return manifest


def _outputs(out: Path, clips_too: bool = True) -> dict[str, bytes]:
    """What a reader sees at the spec's paths (through the links), plus the generated clips."""
    seen = {name: (out / name).read_bytes() for name in NAMES}
    clips = out / "clips"
    if clips_too and clips.is_dir():
        seen |= {f"clips/{p.name}": p.read_bytes() for p in sorted(clips.iterdir())}
    return seen


def _outputs_of(seen: dict[str, bytes], clips_too: bool) -> dict[str, bytes]:
    return {k: v for k, v in seen.items() if clips_too or not k.startswith("clips/")}


def _consistent(out: Path) -> None:
    """All four outputs are of one build: the JSON's divisions match the USD's."""
    doc = json.loads((out / "t.blendspace.json").read_text(encoding="utf-8"))
    divisions = doc["axes"][0]["divisions"]
    assert f"divisions = {divisions}" in (out / "t.blendspace.usda").read_text(encoding="utf-8") or (
        str(divisions) in (out / "t.blendspace.usda").read_text(encoding="utf-8")
    )
    assert (out / "t.png").read_bytes().endswith(b"IEND\xaeB`\x82")


def _build(manifest: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    code = main(["build", str(manifest), "--out", str(out)])
    return code, capsys.readouterr().err


def test_a_rebuild_switches_the_whole_set_and_keeps_the_spec_paths(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    first = _outputs(out)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    assert _outputs(out) == first  # byte-identical, and the same generation folder
    [generation] = (out / ".blendspace" / "t").glob("g-*")
    _project(tmp_path / "p", 50)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    assert _outputs(out) != first
    _consistent(out)
    assert [p.name for p in (out / ".blendspace" / "t").glob("g-*")] != [generation.name]  # old one gone
    assert all((out / name).is_file() for name in NAMES)
    # Generated clips are real files (engines import them; exporters resolve their paths).
    clips = list((out / "clips").iterdir())
    assert clips and all(p.is_file() and not p.is_symlink() for p in clips)


def test_two_manifests_of_one_space_name_into_one_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`build a.yaml b.yaml`, both `name: t` into one folder: b's build replaced a's outputs and
    removed a's generated clips, exit by the findings only. Now b is exit 2 before it writes,
    a's outputs stay, and a third manifest after it is still built."""
    manifest = _project(tmp_path / "p")
    other = manifest.with_name("b.yaml")
    other.write_text(manifest.read_text(encoding="utf-8").replace("divisions: 100", "divisions: 50"), "utf-8")
    third = manifest.with_name("c.yaml")
    third.write_text(manifest.read_text(encoding="utf-8").replace("name: t", "name: u"), "utf-8")
    out = tmp_path / "p" / "build"
    assert main(["build", str(manifest), str(other), str(third)]) == 2
    err = capsys.readouterr().err
    assert f"{other}: builds 't' into {out}, as {manifest} does: its outputs would replace those" in err
    doc = json.loads((out / "t.blendspace.json").read_text(encoding="utf-8"))
    assert doc["axes"][0]["divisions"] == 100  # a's
    assert (out / "u.blendspace.json").is_file()
    assert sorted(p.name for p in (out / "clips").iterdir())  # a's generated clips are still there
    # The same manifest named twice (two spellings of one path) is one space, not a clash.
    capsys.readouterr()
    again = manifest.parent / ".." / manifest.parent.name / manifest.name
    assert main(["build", str(manifest), str(again)]) in (0, 1)
    assert "would replace" not in capsys.readouterr().err


def test_a_glob_over_the_output_s_own_clips_folder_does_not_read_them_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`output.dir: .` with `clips/*.usda`: the build's generated clips land in the folder the
    glob reads. The next build that was not a replay read them as authored takes (generated
    false), dropped their other formats and changed the JSON: two builds of the same inputs gave
    two answers. They are the last build's outputs while they are the files it placed."""
    root = tmp_path / "p"
    manifest = _project(root)
    manifest.write_text(manifest.read_text(encoding="utf-8") + "output: {dir: .}\n", encoding="utf-8")
    assert main(["build", str(manifest)]) in (0, 1)
    first = json.loads((root / "t.blendspace.json").read_text(encoding="utf-8"))
    made = sorted(s["name"] for s in first["samples"] if s["generated"])
    assert made, "the set must need a generated clip for this test"
    for round_ in range(2):
        os.utime(manifest)  # not a replay: the build runs
        capsys.readouterr()
        assert main(["build", str(manifest)]) in (0, 1)
        again = json.loads((root / "t.blendspace.json").read_text(encoding="utf-8"))
        assert sorted(s["name"] for s in again["samples"] if s["generated"]) == made, round_
        assert [s["name"] for s in again["samples"]] == [s["name"] for s in first["samples"]]
    capsys.readouterr()
    assert main(["check", str(manifest), "--format", "json"]) in (0, 1)
    checked = json.loads(capsys.readouterr().out)
    assert not any(d["clips"] and set(d["clips"]) & set(made) for d in checked["diagnostics"])
    # A generated clip the user saved over is theirs: the next build reads it as a take.
    taken = next((root / "clips").glob(f"{made[0]}.usda"))
    content = taken.read_bytes()
    taken.unlink()
    taken.write_bytes(content)  # a new file with the same bytes: no longer the one placed
    os.utime(manifest)
    capsys.readouterr()
    assert main(["build", str(manifest)]) in (0, 1)
    doc = json.loads((root / "t.blendspace.json").read_text(encoding="utf-8"))
    assert {s["name"]: s["generated"] for s in doc["samples"]}[made[0]] is False


def test_an_old_build_of_real_files_is_replaced_by_the_set(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    for name in NAMES:
        (out / name).write_text("from an older version of the tool\n", encoding="utf-8")
    (out / "keep.txt").write_text("a user's file\n", encoding="utf-8")
    assert _build(_project(tmp_path / "p"), out, capsys)[0] in (0, 1)
    _consistent(out)
    assert (out / "keep.txt").read_text(encoding="utf-8") == "a user's file\n"


@pytest.mark.parametrize("previous", [False, True])
@pytest.mark.parametrize(
    "in_the_way", ["t.report.html", "t.blendspace.json", "clips", "clips/turn_mirror.usda"]
)
def test_a_user_s_file_or_folder_where_an_output_goes_is_kept_and_nothing_is_written(
    in_the_way: str, previous: bool, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A folder at an output's path, or a file at the generated clips' folder: exit 2 naming it,
    the user's file or folder untouched (a folder there was deleted), and no generation left
    behind; the rest of a previous build's set still stands."""
    out, manifest = tmp_path / "out", _project(tmp_path / "p")
    before: dict[str, bytes] = {}
    if previous:
        assert _build(manifest, out, capsys)[0] in (0, 1)
        assert (out / "clips" / "turn_mirror.usda").is_file()  # the generated clip this test uses
        before = {name: (out / name).read_bytes() for name in NAMES if name != in_the_way}
        shutil.rmtree(out / "clips") if in_the_way == "clips" else (out / in_the_way).unlink()
        _project(tmp_path / "p", 50)  # the next build is another generation
    user = out / in_the_way
    if in_the_way == "clips":
        user.parent.mkdir(parents=True, exist_ok=True)
        user.write_text("a user's notes\n", encoding="utf-8")
    else:
        user.mkdir(parents=True)
        (user / "notes.txt").write_text("precious\n", encoding="utf-8")
    home = out / ".blendspace" / "t"
    generations = sorted(home.glob("g-*"))
    code, err = _build(manifest, out, capsys)
    assert code == 2, err
    assert f"({user})" in err and "move or rename it" in err and "Traceback" not in err
    if in_the_way == "clips":
        assert user.read_text(encoding="utf-8") == "a user's notes\n"
    else:
        assert (user / "notes.txt").read_text(encoding="utf-8") == "precious\n"
    assert sorted(home.glob("g-*")) == generations  # no generation added
    assert {name: (out / name).read_bytes() for name in before} == before


@pytest.mark.parametrize("listed", [True, False])
def test_a_generated_clip_never_overwrites_a_clip_of_the_user_s(
    listed: bool, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`output.dir: .` puts the generated clips' folder on the project's `clips/`: an authored
    clip (listed in the manifest, or not) whose file has the mirror's name was overwritten by the
    mirror, exit 0. Now exit 2 naming it, the file untouched, nothing written."""
    manifest = _project(tmp_path / "p")
    clips = tmp_path / "p" / "clips"
    authored = clips / "turn_mirror.usda"
    write_usd_clip(generate(GaitSpec("take2", speed=1.4)), authored, meters_per_unit=1.0, up_axis="y")
    before = authored.read_bytes()
    text = manifest.read_text(encoding="utf-8").replace("  - path: clips/*.usda\n", "")
    listed_clips = (
        "  - path: clips/*.usda\n"
        if listed
        else "".join(f"  - path: clips/{name}.usda\n" for name in ("idle", "walk", "turn"))
    )
    manifest.write_text(
        text.replace("clips:\n", "clips:\n" + listed_clips) + "output: {dir: .}\n", encoding="utf-8"
    )
    if listed:  # as another take: its own name, so the mirror keeps `turn_mirror`
        manifest.write_text(
            manifest.read_text(encoding="utf-8").replace(
                "  - path: clips/*.usda\n",
                "".join(f"  - path: clips/{n}.usda\n" for n in ("idle", "walk", "turn"))
                + "  - {path: clips/turn_mirror.usda, name: walk_take2}\n",
            ),
            encoding="utf-8",
        )
    code = main(["build", str(manifest)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert f"({authored})" in err and "never overwritten" in err
    assert authored.read_bytes() == before
    assert not (tmp_path / "p" / ".blendspace").exists() or not list(
        (tmp_path / "p" / ".blendspace").rglob("g-*")
    )
    assert not (tmp_path / "p" / "t.blendspace.json").exists()


def test_generated_clips_a_build_no_longer_makes_leave_the_clips_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A `--no-fix` build after one that mirrored a clip: the mirror's files leave `OUT/clips/`
    (engines import every file there); a generated clip the user edited stays (it is theirs)."""
    out, manifest = tmp_path / "out", _project(tmp_path / "p")
    assert _build(manifest, out, capsys)[0] in (0, 1)
    made = sorted(p.name for p in (out / "clips").iterdir())
    assert "turn_mirror.usda" in made
    code = main(["build", str(manifest), "--out", str(out), "--no-fix"])
    assert code in (0, 1), capsys.readouterr().err
    assert not (out / "clips").exists() or not list((out / "clips").iterdir())
    for in_place in (False, True):
        assert _build(manifest, out, capsys)[0] in (0, 1)  # mirrored again
        edited = out / "clips" / "turn_mirror.usda"
        if in_place:  # a text editor, a script: the generation's hard link changes with it
            with edited.open("a", encoding="utf-8") as stream:
                stream.write("\n# tweaked by hand\n")
        else:  # saved as a DCC saves: a new file renamed over it
            tweaked = edited.with_suffix(".tmp")
            tweaked.write_text(edited.read_text(encoding="utf-8") + "\n# tweaked by hand\n", encoding="utf-8")
            os.replace(tweaked, edited)
        assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
        capsys.readouterr()
        assert edited.read_text(encoding="utf-8").endswith("# tweaked by hand\n")
        edited.unlink()


def test_a_generated_clip_the_build_reads_as_a_source_is_never_removed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`output.dir: .`: the user adopts the mirror as a take (its own `clips:` entry), and the
    manifest reaches it through a symlinked folder (or another letter case on macOS): a `--no-fix`
    build read it, and must not delete it. (A glob alone does not adopt it: that is the last
    build's output, `test_a_glob_over_the_output_s_own_clips_folder_does_not_read_them_back`.)"""
    project = tmp_path / "p"
    manifest = _project(project)
    manifest.write_text(manifest.read_text(encoding="utf-8") + "output: {dir: .}\n", encoding="utf-8")
    assert main(["build", str(manifest)]) in (0, 1)
    mirror = project / "clips" / "turn_mirror.usda"
    assert mirror.is_file()
    (project / "Clips").symlink_to("clips")
    manifest.write_text(
        manifest.read_text(encoding="utf-8").replace(
            "  - path: clips/*.usda\n", "  - path: Clips/*.usda\n  - path: Clips/turn_mirror.usda\n"
        ),
        encoding="utf-8",
    )
    assert main(["build", str(manifest), "--no-fix"]) in (0, 1)
    capsys.readouterr()
    assert mirror.is_file()
    doc = json.loads((project / "t.blendspace.json").read_text(encoding="utf-8"))
    assert "turn_mirror" in [s["name"] for s in doc["samples"]]


def test_a_generated_clip_a_glob_reaches_is_an_output_a_no_fix_build_removes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    project = tmp_path / "p"
    manifest = _project(project)
    manifest.write_text(manifest.read_text(encoding="utf-8") + "output: {dir: .}\n", encoding="utf-8")
    assert main(["build", str(manifest)]) in (0, 1)
    assert (project / "clips" / "turn_mirror.usda").is_file()
    assert main(["build", str(manifest), "--no-fix"]) in (0, 1)
    capsys.readouterr()
    assert not (project / "clips" / "turn_mirror.usda").exists()  # as from any other output folder
    assert sorted(p.name for p in (project / "clips").iterdir()) == ["idle.usda", "turn.usda", "walk.usda"]


def test_a_clip_another_blend_space_published_is_not_removed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two manifests share `build/clips/` and both mirror the same take (the same bytes): one of
    them built `--no-fix` must not remove the clip the other's JSON names."""
    project = tmp_path / "p"
    manifest = _project(project)
    other = project / "u.yaml"
    other.write_text(manifest.read_text(encoding="utf-8").replace("name: t", "name: u"), encoding="utf-8")
    out = project / "build"
    for built in (manifest, other):
        assert main(["build", str(built), "--out", str(out)]) in (0, 1)
    assert main(["build", str(manifest), "--out", str(out), "--no-fix"]) in (0, 1)
    capsys.readouterr()
    doc = json.loads((out / "u.blendspace.json").read_text(encoding="utf-8"))
    named = [s["source"] for s in doc["samples"] if s["generated"]]
    assert named and all((out / source).is_file() for source in named)


def test_a_different_clip_another_blend_space_published_is_never_replaced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two spaces built into one folder, each mirroring its own `turn` (other turn rates, so
    other bytes) under one name: the second build replaced the first's `clips/turn_mirror.usda`,
    which the first's JSON still names, without a word. It is exit 2, nothing written."""
    first = _project(tmp_path / "a")
    second_root = tmp_path / "b"
    second_root.mkdir()
    (second_root / "clips").mkdir()
    for name, spec in {
        "idle": GaitSpec("idle"),
        "walk": GaitSpec("walk", speed=1.4),
        "turn": GaitSpec("turn", turn_rate=60.0),
    }.items():
        write_usd_clip(
            generate(spec), second_root / "clips" / f"{name}.usda", meters_per_unit=1.0, up_axis="y"
        )
    second = second_root / "manifest.yaml"
    second.write_text(first.read_text(encoding="utf-8").replace("name: t", "name: u"), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["build", str(first), "--out", str(out)]) in (0, 1)
    kept = (out / "clips" / "turn_mirror.usda").read_bytes()
    capsys.readouterr()
    assert main(["build", str(second), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "blend space 't' published a different clip of that name in this folder" in err, err
    assert (out / "clips" / "turn_mirror.usda").read_bytes() == kept
    assert not (out / "u.blendspace.json").exists()
    # The first space rebuilt over its own clip is fine.
    assert main(["build", str(first), "--out", str(out)]) in (0, 1)


def test_an_older_build_s_generated_clip_in_the_way_is_replaced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A generated clip written before generation folders (a real file with the provenance record,
    and no record of the build) is the tool's own: the build replaces it."""
    out, manifest = tmp_path / "out", _project(tmp_path / "p")
    assert _build(manifest, out, capsys)[0] in (0, 1)
    mirror = (out / "clips" / "turn_mirror.usda").read_bytes()
    shutil.rmtree(out / ".blendspace")
    for name in NAMES:
        (out / name).unlink()
    (out / "clips" / "turn_mirror.usda").unlink()
    (out / "clips" / "turn_mirror.usda").write_bytes(mirror.replace(b"turn", b"turn", 1))  # a real file now
    assert _build(manifest, out, capsys)[0] in (0, 1)
    assert (out / "clips" / "turn_mirror.usda").read_bytes() == mirror


def test_a_library_that_says_yes_to_a_truncated_png_is_caught(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    before = _outputs(out)
    from blendspace_pipeline import report

    real = report.write_png

    def truncated(doc: object, path: Path) -> None:
        real(doc, path)  # type: ignore[arg-type]
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])  # what a full disk did, with no error reported

    monkeypatch.setattr(report, "write_png", truncated)
    _project(tmp_path / "p", 50)
    code, err = _build(manifest, out, capsys)
    assert code == 2, err
    assert "cannot write the outputs" in err and "incomplete" in err and "hint:" in err
    assert _outputs(out) == before
    assert not list(out.glob(".blendspace-staging-*"))


def test_an_injected_enospc_leaves_the_previous_set(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    before = _outputs(out)
    from blendspace_pipeline import report

    def full(doc: object, path: Path) -> None:
        path.write_bytes(b"\x89PNG")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(report, "write_png", full)
    _project(tmp_path / "p", 50)
    code, err = _build(manifest, out, capsys)
    assert code == 2 and "No space left on device" in err, err
    assert _outputs(out) == before
    assert not list(out.glob(".blendspace-staging-*"))


@pytest.mark.parametrize("which", ["staging", "switch"])
def test_a_failed_rename_leaves_the_previous_set(
    which: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    before = _outputs(out)
    real = os.replace

    def failing(source: str | os.PathLike[str], target: str | os.PathLike[str]) -> None:
        name = Path(target).name
        if (which == "staging" and name.startswith("g-")) or (which == "switch" and name == "current"):
            raise OSError(errno.EIO, os.strerror(errno.EIO), str(target))
        real(source, target)

    monkeypatch.setattr(outputs.os, "replace", failing)
    _project(tmp_path / "p", 50)
    generations = sorted(p.name for p in (out / ".blendspace" / "t").iterdir())
    code, err = _build(manifest, out, capsys)
    assert code == 2 and "Input/output error" in err, err
    # Nothing of the failed build left in the blend space's folder: no generation, no switch link.
    assert sorted(p.name for p in (out / ".blendspace" / "t").iterdir()) == generations
    # Not one new document among the old ones (generated clips are placed just before the switch).
    assert _outputs(out, clips_too=which == "staging") == _outputs_of(before, clips_too=which == "staging")
    _consistent(out)
    monkeypatch.setattr(outputs.os, "replace", real)
    assert _build(manifest, out, capsys)[0] in (0, 1)  # and the next build works
    _consistent(out)


SLOW_WRITER = """
import sys, time
from pathlib import Path
from blendspace_pipeline import report
real = report.write_png
def slow(doc, path):
    real(doc, path)
    Path(sys.argv[3]).write_text("writing")
    time.sleep(60)
report.write_png = slow
from blendspace_pipeline.cli import main
sys.exit(main(["build", sys.argv[1], "--out", sys.argv[2]]))
"""


def test_kill_9_while_writing_leaves_the_previous_set_and_the_next_build_cleans_up(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    before = _outputs(out)
    _project(tmp_path / "p", 50)
    flag = tmp_path / "writing.flag"
    script = tmp_path / "slow_build.py"
    script.write_text(SLOW_WRITER, encoding="utf-8")
    process = subprocess.Popen(
        [sys.executable, str(script), str(manifest), str(out), str(flag)], env={**os.environ}
    )
    try:
        deadline = time.monotonic() + 120
        while not flag.exists():
            assert process.poll() is None, "the build ended before it was killed"
            assert time.monotonic() < deadline, "the build never reached the PNG"
            time.sleep(0.05)
        staging = list(out.glob(".blendspace-staging-*"))
        assert staging and any(staging[0].iterdir())  # killed in the middle of writing
        assert _outputs(out) == before
    finally:
        process.send_signal(signal.SIGKILL)
        process.wait()
    assert _outputs(out) == before  # what was published is untouched
    assert list(out.glob(".blendspace-staging-*"))  # the killed build's leftovers ...
    assert _build(manifest, out, capsys)[0] in (0, 1)
    assert not list(out.glob(".blendspace-staging-*"))  # ... are removed by the next build
    assert _outputs(out) != before
    _consistent(out)


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 40 MB tmpfs: a real file system that fills up. Needs root and mount permission."""
    folder = tmp_path / "disk"
    folder.mkdir()
    if not hasattr(os, "geteuid") or os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a size-limited tmpfs needs root")
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=40m", "tmpfs", str(folder)], capture_output=True, check=False
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode(errors='replace').strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], check=False)


def test_a_really_full_disk_exits_2_and_keeps_the_previous_set(
    small_disk: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = small_disk / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys)[0] in (0, 1)
    before = _outputs(out)
    # Fill the disk up to a few kB: the JSON may still fit, the PNG and the USD do not.
    filler = small_disk / "filler"
    with open(filler, "wb") as stream:
        try:
            while True:
                stream.write(b"\0" * 65536)
                stream.flush()
        except OSError:
            pass
    _project(tmp_path / "p", 50)
    code, err = _build(manifest, out, capsys)
    assert code == 2, err
    assert "cannot write the outputs" in err and len(err.splitlines()) <= 3, err
    assert _outputs(out) == before
    filler.unlink()
    assert _build(manifest, out, capsys)[0] in (0, 1)
    assert not list(out.glob(".blendspace-staging-*"))
    _consistent(out)
