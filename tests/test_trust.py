"""The trust model and the other hostile-user findings that are not exit-2 inputs: plugins outside
the project, `--no-plugins`, the private crash log, control characters in text output, clip
names that look like paths, the BOM, builds independent of the working folder, the lazy CLI."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from blendspace_pipeline import cli
from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip
from blendspace_pipeline.writers.usd_clip import write_usd_clip

HEADER = "schema_version: 1\nname: t\n"
PLUGIN = """
from pathlib import Path
Path({marker!r}).write_text("ran")
"""


@pytest.fixture(autouse=True)
def _isolated(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", "off")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "user-cache"))
    monkeypatch.delenv("BLENDSPACE_RULE_PATH", raising=False)
    monkeypatch.delenv("BLENDSPACE_NO_PLUGINS", raising=False)


def _project(root: Path, extra: str = "") -> Path:
    clips = root / "clips"
    clips.mkdir(parents=True)
    for name, spec in {
        "idle": GaitSpec("idle"),
        "walk": GaitSpec("walk", speed=1.4),
        "turn": GaitSpec("turn", turn_rate=90.0),
    }.items():
        write_usd_clip(generate(spec), clips / f"{name}.usda", meters_per_unit=1.0, up_axis="y")
    manifest = root / "manifest.yaml"
    manifest.write_text(HEADER + "clips:\n  - path: clips/*.usda\n" + extra, encoding="utf-8")
    return manifest


def _plugin(path: Path, marker: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(PLUGIN.format(marker=str(marker)), encoding="utf-8")


@pytest.mark.parametrize("where", ["absolute", "dotdot", "symlink"])
def test_a_plugin_outside_the_project_is_not_run(
    where: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    evil = tmp_path / "outside" / "evil.py"
    marker = tmp_path / "ran.txt"
    _plugin(evil, marker)
    root = tmp_path / "project"
    if where == "absolute":
        entry = str(evil)
    elif where == "dotdot":
        entry = "../outside/evil.py"
    else:
        root.mkdir()
        os.symlink(evil, root / "inside.py")
        entry = "inside.py"
    manifest = _project(root, f"plugins: [{entry!r}]\n")
    code = main(["check", str(manifest), "--format", "json"])
    report = json.loads(capsys.readouterr().out)
    assert not marker.exists()
    assert code == 1
    errors = [d for d in report["diagnostics"] if d["rule"] == "plugin-error"]
    assert errors and "outside the manifest's project" in errors[0]["message"]


def test_a_plugin_inside_the_project_runs_unless_plugins_are_off(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    marker = tmp_path / "ran.txt"
    manifest = _project(tmp_path / "project", "plugins: [rules/studio.py]\n")
    _plugin(tmp_path / "project" / "rules" / "studio.py", marker)
    folder = tmp_path / "rule-path"
    other = tmp_path / "ran-env.txt"
    _plugin(folder / "env_rule.py", other)
    monkeypatch.setenv("BLENDSPACE_RULE_PATH", str(folder))

    assert main(["check", str(manifest), "--no-plugins"]) == 0
    assert not marker.exists() and not other.exists()
    assert "BLENDSPACE_NO_PLUGINS" not in os.environ  # the flag lasts one command
    monkeypatch.setenv("BLENDSPACE_NO_PLUGINS", "1")
    assert main(["build", str(manifest)]) == 0
    assert not marker.exists() and not other.exists()
    monkeypatch.delenv("BLENDSPACE_NO_PLUGINS")
    assert main(["check", str(manifest)]) == 0
    assert marker.read_text() == "ran" and other.read_text() == "ran"
    capsys.readouterr()


def test_rules_naming_a_plugin_rule_warn_when_plugins_are_off(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(
        tmp_path / "p", "plugins: [rules/studio.py]\nrules: {select: [all], ignore: [st-rule]}\n"
    )
    _plugin(tmp_path / "p" / "rules" / "studio.py", tmp_path / "m.txt")
    code = main(["check", str(manifest), "--no-plugins", "--format", "json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0
    [unknown] = [d for d in report["diagnostics"] if d["rule"] == "unknown-rule"]
    assert "--no-plugins" in unknown["hint"]


def _crash(monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(*args: object, **kwargs: object) -> object:
        raise RuntimeError("a bug\nwith a second line\n::error::forged")

    # `check` imports the analysis when it runs (lazily), so the bug is planted at its source.
    monkeypatch.setattr("blendspace_pipeline.pipeline.analysis.analyse", broken)


def test_the_crash_log_is_private_and_one_line_is_printed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path / "p")
    _crash(monkeypatch)
    assert main(["check", str(manifest)]) == 3
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "::error" not in err.split("RuntimeError: a bug")[1].split("(")[0]
    log = tmp_path / "user-cache" / "blendspace-pipeline" / "crash.log"
    assert str(log) in err
    assert "RuntimeError" in log.read_text(encoding="utf-8")
    assert log.stat().st_mode & 0o077 == 0 and log.parent.stat().st_mode & 0o077 == 0


def test_a_planted_crash_log_symlink_is_not_followed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path / "p")
    victim = tmp_path / "victim.txt"
    victim.write_text("precious", encoding="utf-8")
    folder = tmp_path / "user-cache" / "blendspace-pipeline"
    folder.mkdir(parents=True, mode=0o700)
    os.symlink(victim, folder / "crash.log")
    _crash(monkeypatch)
    assert main(["check", str(manifest)]) == 3
    err = capsys.readouterr().err
    assert victim.read_text(encoding="utf-8") == "precious"
    assert len(err.splitlines()) == 1 and "no crash log" in err and "Traceback" not in err


def test_an_unwritable_crash_log_still_gives_one_line_and_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path / "p")
    blocker = tmp_path / "blocker"
    blocker.write_text("a file where the cache folder should be", encoding="utf-8")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocker))
    _crash(monkeypatch)
    assert main(["check", str(manifest)]) == 3
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "no crash log" in err


def test_a_clip_name_with_a_newline_cannot_forge_a_ci_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path / "p")
    manifest.write_text(
        HEADER + "clips:\n  - path: clips/idle.usda\n  - path: clips/walk.usda\n  - path: clips/turn.usda\n"
        '    name: "w\\n::error file=x.py,line=1::forged\\r\\u2028x\\u001b[31m"\n',
        encoding="utf-8",
    )
    for fmt in ("text", "github"):
        # Refused at its line (a name with control characters), and the refusal forges nothing.
        assert main(["check", str(manifest), "--format", fmt]) == 2
        captured = capsys.readouterr()
        out = captured.out + captured.err
        assert not any(line.startswith("::error file=x.py") for line in out.splitlines()), out
        assert "\x1b" not in out and "\u2028" not in out
        assert "control character U+000A" in out


def test_a_clip_name_like_a_path_cannot_write_outside_the_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path / "deep" / "p")
    manifest.write_text(
        HEADER + "clips:\n  - path: clips/idle.usda\n  - path: clips/turn.usda\n    name: ../../x_left\n"
        "  - path: clips/walk.usda\n",
        encoding="utf-8",
    )
    before = {p for p in tmp_path.rglob("*")}
    assert main(["build", str(manifest)]) in (0, 1)
    capsys.readouterr()
    out = tmp_path / "deep" / "p" / "build"
    new = {p for p in tmp_path.rglob("*")} - before
    assert new and all(p == out or out in p.parents for p in new), sorted(new)
    assert any("x_right" in p.name for p in (out / "clips").iterdir())


def test_a_bvh_with_a_utf8_bom_is_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    manifest = _project(tmp_path / "p")
    path = tmp_path / "p" / "clips" / "b.bvh"
    write_bvh_clip(generate(GaitSpec("walk", speed=1.4)), path)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    manifest.write_text(HEADER + "clips:\n  - path: clips/*.usda\n  - path: clips/b.bvh\n", encoding="utf-8")
    code = main(["check", str(manifest), "--format", "json"])
    report = json.loads(capsys.readouterr().out)
    assert code in (0, 1) and not [d for d in report["diagnostics"] if d["rule"] == "invalid-input"]


def test_builds_do_not_depend_on_the_working_folder(tmp_path: Path) -> None:
    manifest = _project(tmp_path / "p")
    outputs = []
    for cwd, manifest_arg, out_arg in (
        (tmp_path / "p", "manifest.yaml", "out1"),
        (tmp_path, str(manifest), str(tmp_path / "p" / "out2")),
    ):
        done = subprocess.run(
            [sys.executable, "-m", "blendspace_pipeline", "build", manifest_arg, "--out", out_arg],
            cwd=cwd,
            capture_output=True,
            text=True,
            check=False,
            env={**os.environ},
        )
        assert done.returncode in (0, 1), done.stderr
        out = tmp_path / "p" / Path(out_arg).name
        outputs.append({name: (out / name).read_bytes() for name in ("t.blendspace.json", "t.report.html")})
    assert outputs[0] == outputs[1]
    doc = json.loads(outputs[0]["t.blendspace.json"])
    assert all(not d["location"]["path"].startswith("/") for d in doc["diagnostics"] if d.get("location"))


def test_the_lazy_help_lines_match_the_commands() -> None:
    for name in cli.COMMANDS:
        module = cli._command_module(name)
        assert module is not None and cli.COMMAND_HELP[name] == module.HELP  # type: ignore[attr-defined]


def test_version_and_help_import_no_command() -> None:
    probe = (
        "import sys; from blendspace_pipeline.cli import main\n"
        "for argv in (['--version'], ['--help']):\n"
        "    try:\n        main(argv)\n    except SystemExit:\n        pass\n"
        "heavy = [m for m in ('numpy', 'pxr', 'scipy', 'pydantic', 'blendspace_pipeline.commands.build') "
        "if m in sys.modules]\n"
        "print('HEAVY', heavy)\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert "HEAVY []" in done.stdout, done.stdout
    assert "build" in done.stdout and "check" in done.stdout  # --help still lists every command
