"""The build server, for real: `blendspace server start` in the background, then commands typed as
a user would (`python -m blendspace_pipeline ...`, a new process each) that it runs.

What must hold: a served command is indistinguishable from a local one (same bytes written, same
exit code, same messages on the caller's own stdout/stderr, the caller's folder and environment),
Ctrl-C still interrupts it, and a server that could run stale code (the tool or a package changed
on disk) or another environment's code never does: the command then runs locally.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import tidy_set
from test_build_e2e import _tree

from blendspace_pipeline.motion.procedural import generate
from blendspace_pipeline.server import address
from blendspace_pipeline.writers.bvh import write_bvh_clip

pytestmark = pytest.mark.skipif(
    not address.supported(), reason="the build server needs fork and Unix sockets"
)


def _project(folder: Path) -> Path:
    for spec in tidy_set().values():
        (folder / "clips").mkdir(parents=True, exist_ok=True)
        write_bvh_clip(generate(spec), folder / "clips" / f"{spec.name}.bvh")
    manifest = folder / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: served\nclips:\n  - path: clips/*.bvh\noutput: {formats: [json, usd, html, png]}\n",
        encoding="utf-8",
    )
    return manifest


def _env(server_dir: Path, cache: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != address.NO_SERVER_VARIABLE}
    env.update({address.SERVER_DIR_VARIABLE: str(server_dir), "BLENDSPACE_CACHE_DIR": str(cache), **extra})
    return env


def _blendspace(*args: str, env: dict[str, str], cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", *args],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=300,
        check=False,
    )


def _status(env: dict[str, str]) -> dict[str, object] | None:
    """What the server says about itself (through the client the commands use)."""
    code = (
        "import json; from blendspace_pipeline.server import client; print(json.dumps(client.ask('status')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    answer: dict[str, object] | None = json.loads(out.stdout)
    return answer


@pytest.fixture
def server(tmp_path: Path) -> Iterator[dict[str, str]]:
    """A running server in a private folder of its own; the environment that reaches it."""
    env = _env(tmp_path / "srv", tmp_path / "cache")
    started = _blendspace("server", "start", "--idle-timeout", "600", env=env)
    assert started.returncode == 0, started.stderr
    assert "started" in started.stdout
    yield env
    stopped = _blendspace("server", "stop", env=env)
    assert stopped.returncode == 0, stopped.stderr
    assert _status(env) is None


def test_a_served_build_writes_what_a_local_build_writes(server: dict[str, str], tmp_path: Path) -> None:
    local_project, served_project = tmp_path / "local", tmp_path / "served"
    _project(local_project)
    _project(served_project)
    # The report is dated by its newest input; the two copies may be written a second apart.
    dated = {**server, "SOURCE_DATE_EPOCH": "1700000000"}
    local = _blendspace(
        "build", "manifest.yaml", env={**dated, address.NO_SERVER_VARIABLE: "1"}, cwd=local_project
    )
    served = _blendspace("build", "manifest.yaml", env=dated, cwd=served_project)  # relative to its cwd
    assert _status(server)["served"] == 1  # type: ignore[index]
    assert served.returncode == local.returncode == 0, served.stderr
    assert served.stdout.replace("served/", "local/") == local.stdout.replace("served/", "local/")
    assert _tree(served_project / "build") == _tree(local_project / "build")
    # The caller's environment reached the command: its cache folder filled.
    assert any((tmp_path / "cache").rglob("*"))


def test_a_caller_with_other_thread_settings_runs_its_command_itself(tmp_path: Path) -> None:
    """usd-core and BLAS fix their thread counts when they load, in the server: a caller that set
    its own (`OPENBLAS_NUM_THREADS=2`) would get the server's. Its command runs in its own process.
    The server here starts without any thread setting (the suite's own environment may hold some:
    a Dask nanny started in the test process sets OMP/MKL/OPENBLAS_NUM_THREADS in its environment,
    `distributed.nanny.pre-spawn-environ`), so the defaults are its settings."""
    from blendspace_pipeline.cpus import THREAD_VARIABLES

    manifest = _project(tmp_path / "p")
    plain = {k: v for k, v in _env(tmp_path / "srv", tmp_path / "cache").items() if k not in THREAD_VARIABLES}
    started = _blendspace("server", "start", "--idle-timeout", "600", env=plain)
    assert started.returncode == 0, started.stderr
    try:
        assert _blendspace("check", str(manifest), env=plain).returncode in (0, 1)
        assert _status(plain)["served"] == 1  # type: ignore[index]
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "PXR_WORK_THREAD_LIMIT"):
            done = _blendspace("check", str(manifest), env={**plain, name: "2"})
            assert done.returncode in (0, 1), done.stderr
            assert _status(plain)["served"] == 1, name  # type: ignore[index]
    finally:
        assert _blendspace("server", "stop", env=plain).returncode == 0


def test_a_served_command_keeps_the_exit_code_and_error_format(
    server: dict[str, str], tmp_path: Path
) -> None:
    manifest = _project(tmp_path)
    manifest.write_text(
        manifest.read_text(encoding="utf-8") + "axes: [{feature: turn_rat}]\n", encoding="utf-8"
    )
    served = _blendspace("check", str(manifest), env=server)
    local = _blendspace("check", str(manifest), env={**server, address.NO_SERVER_VARIABLE: "1"})
    assert _status(server)["served"] == 1  # type: ignore[index]
    assert served.returncode == local.returncode == 2
    assert served.stderr == local.stderr
    assert f"{manifest}:6:" in served.stderr and "Traceback" not in served.stderr


def _as_a_terminal_starts_it() -> None:
    """A command typed in a shell: SIGINT handled and not blocked, whatever this process inherited."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _with_sigint_blocked() -> None:
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})


def _stuck(process: subprocess.Popen[str], env: dict[str, str]) -> str:
    """What to look at when an interrupted command hangs: the caller's signal state (a blocked or
    ignored SIGINT is inherited), whether it still runs, and the server's log."""
    lines = []
    try:
        status = Path(f"/proc/{process.pid}/status").read_text(encoding="utf-8")
        lines += [line for line in status.splitlines() if line.startswith(("State", "Sig"))]
    except OSError as error:
        lines.append(f"no /proc status: {error}")
    process.kill()
    try:  # the server's command process holds the same pipes while it runs on
        out, err = process.communicate(timeout=5)
        lines += [f"stdout: {out[-1000:]}", f"stderr: {err[-1000:]}"]
    except subprocess.TimeoutExpired:
        lines.append("stdout and stderr still held open (by the server's command process)")
    for log in Path(env[address.SERVER_DIR_VARIABLE]).glob("*.log"):
        lines.append(f"{log}: {log.read_text(encoding='utf-8', errors='replace')[-2000:]}")
    return "\n".join(lines)


def test_ctrl_c_interrupts_a_served_command(server: dict[str, str], tmp_path: Path) -> None:
    _interrupt_a_slow_rule(server, tmp_path)


def test_ctrl_c_interrupts_a_command_of_a_server_started_with_sigint_blocked(tmp_path: Path) -> None:
    """A blocked signal is inherited through fork and exec: a server started by a tool that
    blocks SIGINT still lets Ctrl-C reach its commands."""
    env = _env(tmp_path / "srv", tmp_path / "cache")
    started = subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", "server", "start", "--idle-timeout", "600"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
        check=False,
        preexec_fn=_with_sigint_blocked,
    )
    assert started.returncode == 0, started.stderr
    try:
        _interrupt_a_slow_rule(env, tmp_path / "project")
    finally:
        assert _blendspace("server", "stop", env=env).returncode == 0


def _interrupt_a_slow_rule(server: dict[str, str], tmp_path: Path) -> None:
    manifest = _project(tmp_path)
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    started = tmp_path / "rule-started"
    (plugins / "slow_rule.py").write_text(
        textwrap.dedent(
            f"""
            import pathlib, time
            from blendspace_pipeline.api import Rule

            class SlowRule(Rule):
                slug = "studio-slow"
                code = "ST900"
                severity = "info"
                summary = "takes a minute"

                def check(self, space):
                    pathlib.Path({str(started)!r}).touch()
                    time.sleep(120)
                    return []
            """
        ),
        encoding="utf-8",
    )
    env = {**server, "BLENDSPACE_RULE_PATH": str(plugins)}
    process = subprocess.Popen(
        [sys.executable, "-m", "blendspace_pipeline", "check", str(manifest)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_as_a_terminal_starts_it,
    )
    deadline = time.monotonic() + 120
    while not started.exists() and time.monotonic() < deadline and process.poll() is None:
        time.sleep(0.1)
    assert started.exists(), process.communicate()
    process.send_signal(signal.SIGINT)
    try:
        _out, err = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail(f"Ctrl-C did not stop the command within 60 s:\n{_stuck(process, server)}")
    assert process.returncode == 130, err
    assert "interrupted" in err
    assert _status(server)["served"] == 1  # type: ignore[index]


def test_a_server_whose_packages_changed_starts_again_and_the_command_runs_locally(tmp_path: Path) -> None:
    extra = tmp_path / "site"  # a folder on sys.path, as site-packages is
    extra.mkdir()
    env = _env(tmp_path / "srv", tmp_path / "cache", PYTHONPATH=str(extra))
    assert _blendspace("server", "start", "--idle-timeout", "600", env=env).returncode == 0
    try:
        before = _status(env)
        assert before is not None and before["current"] is True
        time.sleep(0.05)
        (extra / "new_package.py").write_text("", encoding="utf-8")  # `pip install` of something
        manifest = _project(tmp_path / "project")
        result = _blendspace("check", str(manifest), env=env)
        assert result.returncode in (0, 1), result.stderr
        # The command ran here; the server, not having served it, starts again with the new code.
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            after = _status(env)
            if after is not None and after["started"] != before["started"]:
                break
            time.sleep(0.1)
        assert after is not None and after["started"] != before["started"], after
        assert after["current"] is True and after["matches"] is True and after["served"] == 0
        assert _blendspace("check", str(manifest), env=env).returncode in (0, 1)
        assert _status(env)["served"] == 1  # type: ignore[index]
    finally:
        _blendspace("server", "stop", env=env)


def test_a_caller_with_another_sys_path_runs_locally_and_the_server_stays(
    server: dict[str, str], tmp_path: Path
) -> None:
    other = tmp_path / "other"
    other.mkdir()
    manifest = _project(tmp_path / "project")
    result = _blendspace("check", str(manifest), env={**server, "PYTHONPATH": str(other)})
    assert result.returncode in (0, 1), result.stderr
    answer = _status(server)
    assert answer is not None and answer["served"] == 0
    status = _blendspace("server", "status", env={**server, "PYTHONPATH": str(other)})
    assert "does not serve this shell" in status.stdout


def test_status_and_stop_without_a_server(tmp_path: Path) -> None:
    env = _env(tmp_path / "srv", tmp_path / "cache")
    status = _blendspace("server", "status", env=env)
    assert status.returncode == 1 and "not running" in status.stdout
    stop = _blendspace("server", "stop", env=env)
    assert stop.returncode == 0 and "not running" in stop.stdout


def test_a_shared_server_folder_is_refused_and_ignored(tmp_path: Path) -> None:
    folder = tmp_path / "srv"
    folder.mkdir(mode=0o755)
    folder.chmod(0o755)
    env = _env(folder, tmp_path / "cache")
    result = _blendspace("server", "start", env=env)
    assert result.returncode == 2
    assert "can be opened by other users" in result.stderr and "Traceback" not in result.stderr
    # A socket planted in a folder others can write is never used.
    assert address.private_problem(folder) is not None


def test_an_idle_server_stops_by_itself(tmp_path: Path) -> None:
    env = _env(tmp_path / "srv", tmp_path / "cache")
    assert _blendspace("server", "start", "--idle-timeout", "1", env=env).returncode == 0
    deadline = time.monotonic() + 30
    while _status(env) is not None and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _status(env) is None
    assert not list((tmp_path / "srv").glob("*.sock"))


def test_the_fingerprint_moves_with_the_code_and_sys_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    before = address.fingerprint()
    assert address.fingerprint() == before
    script_folder = [str(tmp_path / "elsewhere"), *sys.path[1:]]
    monkeypatch.setattr(sys, "path", script_folder)  # sys.path[0] is the script's folder: not counted
    assert address.fingerprint() == before
    monkeypatch.setattr(sys, "path", [*sys.path, str(tmp_path)])
    changed = address.fingerprint()
    assert changed != before
    time.sleep(0.01)
    (tmp_path / "x.py").write_text("", encoding="utf-8")
    assert address.fingerprint() != changed


def test_main_called_with_a_list_runs_in_process(
    server: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from blendspace_pipeline.cli import main

    for key, value in server.items():
        monkeypatch.setenv(key, value)
    monkeypatch.delenv(address.NO_SERVER_VARIABLE, raising=False)
    assert main(["check", str(_project(tmp_path))]) in (0, 1)
    assert _status(server)["served"] == 0  # type: ignore[index]


def test_server_start_where_there_is_no_fork_says_so(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from blendspace_pipeline.cli import main

    monkeypatch.setattr(address, "supported", lambda: False)
    assert main(["server", "start"]) == 2
    assert "not available on this platform" in capsys.readouterr().err


def test_a_served_command_s_client_imports_only_the_client(server: dict[str, str], tmp_path: Path) -> None:
    """The caller of a served command is a Python start, the client (json, socket, hashlib) and a
    wait: argparse, the error types, traceback and the pipeline load only in a local run."""
    manifest = _project(tmp_path)
    probe = (
        "import sys\n"
        f"sys.argv = ['blendspace', 'check', {str(manifest)!r}]\n"
        "from blendspace_pipeline import cli\n"
        "code = cli.main()\n"  # a local run would end the process here (cli._exit_now)
        "local = ('argparse', 'traceback', 'blendspace_pipeline.errors', 'numpy', 'pydantic')\n"
        "print('LOADED', [m for m in local if m in sys.modules], 'CODE', code)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, env=server, check=False
    )
    assert "LOADED [] CODE" in done.stdout, done.stdout + done.stderr
    assert _status(server)["served"] == 1  # type: ignore[index]


@pytest.mark.skipif(
    not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
    reason="needs two CPUs to restrict a caller to one",
)
def test_a_served_command_runs_on_the_caller_s_cpus_and_niceness(
    server: dict[str, str], tmp_path: Path
) -> None:
    """`taskset -c N nice -n 5 blendspace build`: the served command runs on CPU N at niceness 5
    (and `--jobs auto` counts one CPU), as the command would in the caller's own process, with
    BLAS in its own thread as there."""
    manifest = _project(tmp_path)
    plugins, seen = tmp_path / "plugins", tmp_path / "seen.json"
    plugins.mkdir()
    (plugins / "where_rule.py").write_text(
        textwrap.dedent(
            f"""
            import json, os, pathlib, threading
            import numpy
            from blendspace_pipeline.api import Rule
            from blendspace_pipeline.cpus import auto_jobs

            class WhereRule(Rule):
                slug = "studio-where"
                code = "ST901"
                severity = "info"
                summary = "says where it runs"

                def check(self, space):
                    matrix = numpy.ones((200, 200))
                    matrix @ matrix  # BLAS: no thread of its own (cpus.one_blas_thread)
                    threads = len(os.listdir("/proc/self/task")) - threading.active_count()
                    where = {{"pid": os.getpid(), "cpus": sorted(os.sched_getaffinity(0)),
                              "nice": os.nice(0), "jobs": auto_jobs(), "threads": threads}}
                    pathlib.Path({str(seen)!r}).write_text(json.dumps(where))
                    return []
            """
        ),
        encoding="utf-8",
    )
    cpu = max(os.sched_getaffinity(0))

    def as_taskset_and_nice() -> None:
        os.sched_setaffinity(0, {cpu})
        os.nice(5)

    env = {**server, "BLENDSPACE_RULE_PATH": str(plugins)}
    env.pop("BLENDSPACE_JOBS", None)
    done = subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", "check", str(manifest)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=as_taskset_and_nice,
        check=False,
    )
    assert done.returncode in (0, 1), done.stderr
    assert _status(server)["served"] == 1  # type: ignore[index]
    where = json.loads(seen.read_text(encoding="utf-8"))
    assert where["cpus"] == [cpu] and where["jobs"] == 1 and where["threads"] == 0
    assert where["nice"] == min(19, os.nice(0) + 5)
