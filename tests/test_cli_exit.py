"""`blendspace` ends its process without the interpreter's teardown (`cli._exit_now`): what it
printed still arrives whole, through a pipe or into a file, and its exit status is the command's."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from contextlib import redirect_stdout
from pathlib import Path

from blendspace_pipeline.cli import main


def _command(*words: str, stdout: int | object = subprocess.PIPE) -> subprocess.CompletedProcess[bytes]:
    env = {**os.environ, "BLENDSPACE_NO_SERVER": "1"}
    return subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", *words],
        stdout=stdout,
        stderr=subprocess.PIPE,
        env=env,
        timeout=120,
    )


def test_everything_printed_arrives_through_a_pipe_and_into_a_file(tmp_path: Path) -> None:
    here = io.StringIO()
    with redirect_stdout(here):
        assert main(["schema"]) == 0
    assert len(here.getvalue()) > 10_000  # more than one pipe buffer's worth
    piped = _command("schema")
    assert piped.returncode == 0 and piped.stdout.decode() == here.getvalue()
    with (tmp_path / "schema.json").open("wb") as stream:
        assert _command("schema", stdout=stream).returncode == 0
    assert (tmp_path / "schema.json").read_text(encoding="utf-8") == here.getvalue()


def test_the_exit_status_is_the_command_s(tmp_path: Path) -> None:
    manifest = tmp_path / "m.yaml"
    manifest.write_text("schema_version: 1\nclipz: []\n", encoding="utf-8")
    done = _command("check", str(manifest))
    assert done.returncode == 2
    assert b"clipz" in done.stderr


def test_a_setting_in_the_environment_that_is_not_a_whole_number_is_bad_input(tmp_path: Path) -> None:
    """`SOURCE_DATE_EPOCH=1.5e9` ended `check` with exit 3 (numpy's import reads it) and was
    ignored by a served command; `BLENDSPACE_MAX_FRAMES=abc` was ignored. Both are exit 2 naming
    the variable, in a process of the command's own (as a user runs it)."""
    manifest = Path(__file__).parent.parent / "sample_project" / "manifest.yaml"
    for name, value in (
        ("SOURCE_DATE_EPOCH", "1.5e9"),
        ("SOURCE_DATE_EPOCH", "abc"),
        ("SOURCE_DATE_EPOCH", "1700000000000"),  # milliseconds: "year 55840 is out of range", exit 3
        ("SOURCE_DATE_EPOCH", "\u00b2"),  # a digit to str.isdigit, not to int()
        ("BLENDSPACE_MAX_FRAMES", "abc"),
        ("BLENDSPACE_MAX_FRAMES", "0"),  # was replaced by the default without a word
    ):
        env = {**os.environ, "BLENDSPACE_NO_SERVER": "1", "BLENDSPACE_CACHE_DIR": str(tmp_path), name: value}
        done = subprocess.run(
            [sys.executable, "-m", "blendspace_pipeline", "check", str(manifest)],
            capture_output=True,
            env=env,
            timeout=120,
        )
        err = done.stderr.decode()
        assert done.returncode == 2, err
        assert err.startswith(f"{name}={value!r} is not a whole number") and "Traceback" not in err
    env = {
        **os.environ,
        "BLENDSPACE_NO_SERVER": "1",
        "BLENDSPACE_CACHE_DIR": str(tmp_path),
        "SOURCE_DATE_EPOCH": "1700000000",
    }
    done = subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", "check", str(manifest)],
        capture_output=True,
        env=env,
        timeout=120,
    )
    assert done.returncode in (0, 1), done.stderr.decode()
