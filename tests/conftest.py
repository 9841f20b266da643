"""Shared test fixtures: where ../shared/data is, and a clean measurement cache per test."""

from __future__ import annotations

import os
from pathlib import Path
from typing import NoReturn

import pytest

from blendspace_pipeline.cpus import own_process

# As the `blendspace` command does for its own process, before any test loads usd-core or numpy:
# tests call the command in this process, which then forks workers that read USD and use BLAS.
own_process()

from blendspace_pipeline.motion.procedural import GaitSpec  # noqa: E402 - after own_process

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = REPO.parent / "shared" / "data"

# `blendspace` ends its own process with os._exit (cli._exit_now). Called in the pytest process, it
# would end the run at once, with exit status 0 and the remaining tests unrun: there it is an error.
# Forked children (writers, workers, served commands) have other pids and exit as before.
_TEST_PROCESS = os.getpid()
_real_exit = os._exit


def _guarded_exit(code: int) -> NoReturn:
    if os.getpid() == _TEST_PROCESS:
        raise RuntimeError(f"os._exit({code}) in the pytest process would end the test run silently")
    _real_exit(code)


os._exit = _guarded_exit


def shared_data(*parts: str) -> Path:
    """A file under ../shared/data; the test is skipped when the shared folder is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} is not present (the shared data folder sits beside the repository)")
    return path


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BLENDSPACE_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
    # A developer's running build server must not answer the tests' `blendspace` processes.
    monkeypatch.setenv("BLENDSPACE_NO_SERVER", "1")
    monkeypatch.setenv("BLENDSPACE_SERVER_DIR", str(tmp_path_factory.mktemp("server")))
    monkeypatch.delenv("BLENDSPACE_RULE_PATH", raising=False)
    # Commands measure in this process unless a test asks for workers (`--jobs N`, or `auto`
    # in test_cpus): many tests count or patch what happens in it. BLENDSPACE_TEST_JOBS runs
    # the suite with another default (the error-path tests also run so in CI).
    monkeypatch.setenv("BLENDSPACE_JOBS", os.environ.get("BLENDSPACE_TEST_JOBS", "1"))


def tidy_set() -> dict[str, GaitSpec]:
    """A set with no error-severity findings: idle, straight and turning walks, turns in place and
    a backward walk (clip name -> the spec it is generated from)."""
    specs = [
        GaitSpec("idle", duration=1.0),
        GaitSpec("walk_fwd", speed=1.4, duration=1.0),
        GaitSpec("walk_left", speed=1.4, turn_rate=60.0, duration=1.0),
        GaitSpec("walk_right", speed=1.4, turn_rate=-60.0, duration=1.0),
        GaitSpec("tip_left", turn_rate=90.0, duration=1.0),
        GaitSpec("tip_right", turn_rate=-90.0, duration=1.0),
        GaitSpec("walk_bwd", speed=1.1, direction=180.0, duration=1.0),
    ]
    return {spec.name: spec for spec in specs}
