"""`--jobs auto`: the CPUs a build may use, read from the affinity mask and the cgroup quota.

The cgroup trees here are folders laid out as `/proc/self` and `/sys/fs/cgroup` are, in the
formats the kernel writes (cgroup v1, v2, hybrid, and a container's namespaced view).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from conftest import tidy_set

from blendspace_pipeline.cli import main
from blendspace_pipeline.commands import _shared
from blendspace_pipeline.cpus import JOBS_VARIABLE, auto_jobs, cgroup_cpu_quota, usable_cpus
from blendspace_pipeline.motion.procedural import generate
from blendspace_pipeline.writers.bvh import write_bvh_clip

V2_MOUNT = (
    "29 23 0:26 / /sys/fs/cgroup rw,nosuid,nodev,noexec,relatime shared:4 - cgroup2 cgroup2 rw,nsdelegate"
)
V1_CPU_MOUNT = "32 31 0:29 {root} /sys/fs/cgroup/cpu,cpuacct rw,relatime - cgroup cgroup rw,cpu,cpuacct"
V1_CPUSET_MOUNT = "34 31 0:31 / /sys/fs/cgroup/cpuset rw,relatime - cgroup cgroup rw,cpuset"


def _affinity() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # macOS, Windows
        return os.cpu_count() or 1


def _tree(root: Path, cgroup: str, mountinfo: list[str], files: dict[str, str]) -> Path:
    (root / "proc/self").mkdir(parents=True)
    (root / "proc/self/cgroup").write_text(cgroup, encoding="utf-8")
    (root / "proc/self/mountinfo").write_text("\n".join(mountinfo) + "\n", encoding="utf-8")
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text + "\n", encoding="utf-8")
    return root


def test_a_v2_quota_of_one_and_a_half_cpus_counts_as_two(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        "0::/system.slice/runner.service\n",
        [V2_MOUNT],
        {"sys/fs/cgroup/system.slice/runner.service/cpu.max": "150000 100000"},
    )
    assert cgroup_cpu_quota(root) == 1.5
    assert usable_cpus(root) == min(2, _affinity())


def test_the_tightest_quota_of_the_cgroup_and_its_ancestors_wins(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        "0::/ci/job/step\n",
        [V2_MOUNT],
        {
            "sys/fs/cgroup/ci/job/step/cpu.max": "max 100000",
            "sys/fs/cgroup/ci/job/cpu.max": "400000 100000",
            "sys/fs/cgroup/ci/cpu.max": "100000 100000",
            "sys/fs/cgroup/cpu.max": "max 100000",
        },
    )
    assert cgroup_cpu_quota(root) == 1.0
    assert usable_cpus(root) == 1


def test_no_quota_leaves_the_affinity_mask(tmp_path: Path) -> None:
    root = _tree(tmp_path, "0::/user.slice\n", [V2_MOUNT], {"sys/fs/cgroup/user.slice/cpu.max": "max 100000"})
    assert cgroup_cpu_quota(root) is None
    assert usable_cpus(root) == _affinity()


def test_a_v1_cfs_quota_inside_a_docker_container(tmp_path: Path) -> None:
    """Without a cgroup namespace the membership names the host's path of the cgroup, and the
    mount's root is the container's cgroup: the container's quota lies at the mount point, and a
    sub-cgroup's (here a build step's) below it."""
    container = "/docker/3f2a9c"
    files = {
        "sys/fs/cgroup/cpu,cpuacct/cpu.cfs_quota_us": "200000",
        "sys/fs/cgroup/cpu,cpuacct/cpu.cfs_period_us": "100000",
    }
    root = _tree(
        tmp_path / "container",
        f"5:cpuset:/\n4:cpu,cpuacct:{container}\n0::/\n",
        [V1_CPUSET_MOUNT, V1_CPU_MOUNT.format(root=container)],
        files,
    )
    assert cgroup_cpu_quota(root) == 2.0
    step = _tree(
        tmp_path / "step",
        f"4:cpu,cpuacct:{container}/step\n",
        [V1_CPU_MOUNT.format(root=container)],
        {
            **files,
            "sys/fs/cgroup/cpu,cpuacct/step/cpu.cfs_quota_us": "100000",
            "sys/fs/cgroup/cpu,cpuacct/step/cpu.cfs_period_us": "100000",
        },
    )
    assert cgroup_cpu_quota(step) == 1.0


def test_v1_without_a_quota_and_a_cpuacct_only_mount(tmp_path: Path) -> None:
    """-1 is v1's "no quota"; a `cpuacct` controller is not `cpu`."""
    root = _tree(
        tmp_path,
        "3:cpuacct:/\n2:cpu:/\n",
        [
            "33 31 0:30 / /sys/fs/cgroup/cpuacct rw,relatime - cgroup cgroup rw,cpuacct",
            "32 31 0:29 / /sys/fs/cgroup/cpu rw,relatime - cgroup cgroup rw,cpu",
        ],
        {
            "sys/fs/cgroup/cpuacct/cpu.cfs_quota_us": "50000",  # not read: not the cpu controller
            "sys/fs/cgroup/cpuacct/cpu.cfs_period_us": "100000",
            "sys/fs/cgroup/cpu/cpu.cfs_quota_us": "-1",
            "sys/fs/cgroup/cpu/cpu.cfs_period_us": "100000",
        },
    )
    assert cgroup_cpu_quota(root) is None


def test_a_v2_mount_of_the_container_s_own_cgroup(tmp_path: Path) -> None:
    """A container without a cgroup namespace on a v2 host: the mount's root is the container's
    cgroup and the membership is the host's path to it."""
    root = _tree(
        tmp_path,
        "0::/system.slice/docker-3f2a.scope\n",
        ["29 23 0:26 /system.slice/docker-3f2a.scope /sys/fs/cgroup rw,relatime - cgroup2 cgroup2 rw"],
        {"sys/fs/cgroup/cpu.max": "300000 100000"},
    )
    assert cgroup_cpu_quota(root) == 3.0


def test_a_mount_of_another_part_of_the_tree_is_not_read(tmp_path: Path) -> None:
    root = _tree(
        tmp_path,
        "0::/ci/job\n",
        ["29 23 0:26 /other /sys/fs/cgroup rw,relatime - cgroup2 cgroup2 rw"],
        {"sys/fs/cgroup/cpu.max": "100000 100000", "sys/fs/cgroup/ci/job/cpu.max": "100000 100000"},
    )
    assert cgroup_cpu_quota(root) is None


def test_a_hybrid_host_reads_the_v1_cpu_controller(tmp_path: Path) -> None:
    """systemd's hybrid layout: v1 controllers, and cgroup2 (without `cpu.max`) at /unified."""
    root = _tree(
        tmp_path,
        "2:cpu:/build\n1:name=systemd:/build\n0::/build\n",
        [
            "31 23 0:28 / /sys/fs/cgroup rw,relatime - tmpfs tmpfs rw,mode=755",
            "32 31 0:29 / /sys/fs/cgroup/cpu rw,relatime - cgroup cgroup rw,cpu",
            "41 31 0:38 / /sys/fs/cgroup/unified rw,relatime - cgroup2 cgroup2 rw",
        ],
        {
            "sys/fs/cgroup/cpu/build/cpu.cfs_quota_us": "250000",
            "sys/fs/cgroup/cpu/build/cpu.cfs_period_us": "100000",
            "sys/fs/cgroup/unified/build/cgroup.procs": "1",
        },
    )
    assert cgroup_cpu_quota(root) == 2.5
    assert usable_cpus(root) == min(3, _affinity())


def test_escaped_mount_points_are_read(tmp_path: Path) -> None:
    """The kernel writes a space in a mount point as \\040."""
    root = _tree(
        tmp_path,
        "0::/job\n",
        [r"29 23 0:26 / /mnt/cgroup\040root rw,relatime - cgroup2 cgroup2 rw"],
        {"mnt/cgroup root/job/cpu.max": "200000 100000"},
    )
    assert cgroup_cpu_quota(root) == 2.0


def test_unreadable_or_odd_cgroup_files_mean_no_quota(tmp_path: Path) -> None:
    assert cgroup_cpu_quota(tmp_path / "nothing") is None
    root = _tree(
        tmp_path / "odd",
        "garbage\n0::/a\n",
        ["short line", "1 2 3 - cgroup2", V2_MOUNT],
        {"sys/fs/cgroup/a/cpu.max": "lots 0"},
    )
    assert cgroup_cpu_quota(root) is None


def test_this_machine() -> None:
    assert 1 <= usable_cpus() <= (os.cpu_count() or 1)
    assert auto_jobs() == (usable_cpus() if sys.platform.startswith("linux") else 1)


def test_jobs_auto_is_the_default_and_can_be_given(monkeypatch: pytest.MonkeyPatch) -> None:
    """What argparse hands the command: without --jobs, BLENDSPACE_JOBS, else `auto_jobs()`."""
    monkeypatch.delenv(JOBS_VARIABLE)
    monkeypatch.setattr(_shared, "auto_jobs", lambda: 5)
    seen: list[int] = []
    from blendspace_pipeline.commands import check

    def record(args: object) -> int:
        seen.append(args.jobs)  # type: ignore[attr-defined]
        return 0

    monkeypatch.setattr(check, "run", record)
    for words in (
        ["check", "m.yaml"],
        ["check", "m.yaml", "--jobs", "auto"],
        ["check", "m.yaml", "--jobs", "3"],
    ):
        assert main(words) == 0
    monkeypatch.setenv(JOBS_VARIABLE, "4")
    assert main(["check", "m.yaml"]) == 0
    assert main(["check", "m.yaml", "--jobs", "2"]) == 0  # the option wins over the variable
    monkeypatch.setenv(JOBS_VARIABLE, "Auto")
    assert main(["check", "m.yaml"]) == 0
    assert seen == [5, 5, 3, 4, 2, 5]


def test_a_bad_jobs_variable_is_bad_input(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv(JOBS_VARIABLE, "lots")
    assert main(["check", "m.yaml"]) == 2
    err = capsys.readouterr().err
    assert "'lots' is not a whole number or 'auto'" in err and JOBS_VARIABLE in err
    assert "Traceback" not in err


def test_a_default_build_writes_what_one_process_writes(tmp_path: Path) -> None:
    """The default (`auto`: two workers on a two-CPU runner) against `--jobs 1`, each in a process
    of its own as a user runs it: the same exit code and the same bytes."""
    if auto_jobs() < 2:
        pytest.skip("`auto` is one process here: nothing to compare")
    clips = tmp_path / "clips"
    clips.mkdir()
    for name, spec in tidy_set().items():
        write_bvh_clip(generate(replace(spec, name=name)), clips / f"{name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
    env = {key: value for key, value in os.environ.items() if key != JOBS_VARIABLE}
    codes = []
    for out, extra in (("default", []), ("one", ["--jobs", "1"])):
        env["BLENDSPACE_CACHE_DIR"] = str(tmp_path / f"cache-{out}")
        command = [
            sys.executable,
            "-m",
            "blendspace_pipeline",
            "build",
            str(manifest),
            "--out",
            str(tmp_path / out),
        ]
        done = subprocess.run([*command, *extra], env=env, capture_output=True, text=True, timeout=300)
        assert "Traceback" not in done.stderr, done.stderr
        codes.append(done.returncode)
    assert codes[0] == codes[1] and codes[0] in (0, 1)
    default, one = (
        sorted(p.relative_to(tmp_path / out) for p in (tmp_path / out).rglob("*") if p.is_file())
        for out in ("default", "one")
    )
    assert default == one and len(default) >= 4
    for name in default:
        assert (tmp_path / "default" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name


def _check_in_its_own_process(
    manifest: Path, plugins: Path, without: tuple[str, ...], extra: dict[str, str]
) -> subprocess.CompletedProcess[str]:
    """`blendspace check` in a process of its own with the rule plugins in ``plugins`` and no
    cache, the variables ``without`` left out of this environment and ``extra`` added."""
    env = {k: v for k, v in os.environ.items() if k not in without}
    env.update({"BLENDSPACE_RULE_PATH": str(plugins), "BLENDSPACE_CACHE_DIR": "off", **extra})
    done = subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", "check", str(manifest), "--jobs", "1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode in (0, 1), done.stderr
    return done


def _project_with_plugins(tmp_path: Path, suffix: str) -> tuple[Path, Path]:
    """Three clips of the tidy set as ``suffix`` files, their manifest, and an empty folder for a
    rule plugin that reports what the command's process looks like."""
    clips = tmp_path / "clips"
    clips.mkdir()
    for name, spec in list(tidy_set().items())[:3]:
        clip = generate(replace(spec, name=name))
        if suffix == "usda":
            from blendspace_pipeline.writers.usd_clip import write_usd_clip

            write_usd_clip(clip, clips / f"{name}.usda", meters_per_unit=1.0, up_axis="y")
        else:
            write_bvh_clip(clip, clips / f"{name}.bvh")
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(f"schema_version: 1\nname: t\nclips:\n  - path: clips/*.{suffix}\n", encoding="utf-8")
    plugins = tmp_path / "plugins"
    plugins.mkdir()
    return manifest, plugins


@pytest.mark.parametrize("given", [None, "2"])
def test_a_command_reads_usd_without_tbb_threads_and_says_nothing_about_it(
    given: str | None, tmp_path: Path
) -> None:
    """`blendspace` keeps usd-core to one thread in its own process (TBB's workers do not survive
    the forks of `--jobs`), quietly, unless the user set PXR_WORK_THREAD_LIMIT."""
    pytest.importorskip("pxr")
    manifest, plugins = _project_with_plugins(tmp_path, "usda")
    seen = tmp_path / "seen.txt"
    (plugins / "threads_rule.py").write_text(
        "import pathlib\n"
        "from pxr import Work\n"
        "from blendspace_pipeline.api import Rule\n\n"
        "class ThreadsRule(Rule):\n"
        "    slug = 'studio-threads'\n"
        "    code = 'ST902'\n"
        "    severity = 'info'\n"
        "    summary = 'says how many threads USD may use'\n\n"
        "    def check(self, space):\n"
        f"        pathlib.Path({str(seen)!r}).write_text(str(Work.GetConcurrencyLimit()))\n"
        "        return []\n",
        encoding="utf-8",
    )
    usd = ("PXR_WORK_THREAD_LIMIT", "TF_ENV_SETTING_ALERTS_ENABLED")
    done = _check_in_its_own_process(manifest, plugins, usd, {} if given is None else {usd[0]: given})
    assert seen.read_text(encoding="utf-8") == (given or "1")
    if given is None:
        assert "PXR_WORK_THREAD_LIMIT" not in done.stderr and "overridden" not in done.stderr


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads in /proc")
@pytest.mark.parametrize("given", [None, {"OMP_NUM_THREADS": "2"}])
def test_a_command_runs_blas_in_its_own_thread(given: dict[str, str] | None, tmp_path: Path) -> None:
    """`blendspace` runs numpy's and scipy's BLAS without threads of their own in its process (they
    spin after every call, on the CPUs the --jobs workers use), unless the user set a count."""
    manifest, plugins = _project_with_plugins(tmp_path, "bvh")
    seen = tmp_path / "seen.json"
    (plugins / "blas_rule.py").write_text(
        "import json, os, pathlib, threading\n"
        "import numpy, scipy.linalg\n"
        "from blendspace_pipeline.api import Rule\n\n"
        "class BlasRule(Rule):\n"
        "    slug = 'studio-blas'\n"
        "    code = 'ST903'\n"
        "    severity = 'info'\n"
        "    summary = 'counts the threads BLAS adds'\n\n"
        "    def check(self, space):\n"
        "        matrix = numpy.random.default_rng(0).random((200, 200))\n"
        "        scipy.linalg.lu_factor(matrix @ matrix)\n"
        "        native = len(os.listdir('/proc/self/task')) - threading.active_count()\n"
        "        names = ('OPENBLAS_NUM_THREADS', 'GOTO_NUM_THREADS', 'OMP_NUM_THREADS')\n"
        f"        pathlib.Path({str(seen)!r}).write_text(json.dumps(\n"
        "            {'native': native, 'env': {n: os.environ[n] for n in names if n in os.environ}}))\n"
        "        return []\n",
        encoding="utf-8",
    )
    blas = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
    _check_in_its_own_process(manifest, plugins, blas, given or {})
    found = json.loads(seen.read_text(encoding="utf-8"))
    if given is None:
        assert found == {"native": 0, "env": {"OPENBLAS_NUM_THREADS": "1"}}
    else:
        assert found["env"] == given  # the user's count is theirs: nothing added
        if _affinity() > 1:
            assert found["native"] >= 1  # and BLAS does start its threads (the test can fail)


def test_local_processes_are_capped_at_four_per_cpu(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`index --workers 1000` on 2 CPUs started a thousand processes (the machine ran out of
    memory); `--jobs 1000` forked a worker per clip. Measuring is CPU-bound: at most 4 per CPU."""
    from blendspace_pipeline import cpus
    from blendspace_pipeline.commands._shared import _jobs

    monkeypatch.setattr(cpus, "usable_cpus", lambda root=None: 2)
    assert cpus.capped_processes(8, "--jobs") == 8 and capsys.readouterr().err == ""
    assert cpus.capped_processes(1000, "--workers") == 8
    assert "--workers 1000 is more than 4 processes per CPU here (2 CPUs): using 8" in capsys.readouterr().err
    assert _jobs("1000") == 8
