"""How many processes a command may usefully run: `--jobs auto`, the command line's default.

`os.cpu_count()` counts the host's CPUs. A build in a container or a CI runner often may use
fewer: its affinity mask (`taskset`, a cpuset) and its cgroup's CPU quota (`docker --cpus 2`, a
Kubernetes CPU limit, a hosted runner) say how many, and a build that starts one worker per host
CPU under a 2-CPU quota is throttled in bursts and runs slower than with two. This reads both,
as the JVM and Go runtimes do.
"""

from __future__ import annotations

import math
import os
import re
import sys
from collections.abc import Mapping, MutableMapping
from pathlib import Path

# `--jobs`' default when the option is not given: a number or "auto" (a CI job sets it once for
# every command and hook it runs).
JOBS_VARIABLE = "BLENDSPACE_JOBS"


def fork_safe_usd(env: MutableMapping[str, str] = os.environ) -> None:
    """Keep usd-core from starting its TBB worker threads in this command's process.

    The command forks workers (measuring, foot-skate) and writers after it may have read or written
    USD itself (a style layer's two clips, the prepared clips of the first blends, the USD writer).
    TBB's pool does not survive a fork: a child that then reads USD waits forever on workers that
    exist only in its parent (seen as a measuring worker hung in `futex_wait`). One USD thread
    costs nothing here: a clip's stage is read serially anyway. Set before usd-core loads; a value
    the user set is kept (and the banner usd-core prints for a changed setting is not shown). Only
    the command line does this: the Python API never changes its host's USD (Maya, Houdini)."""
    env.setdefault("PXR_WORK_THREAD_LIMIT", "1")
    env.setdefault("TF_ENV_SETTING_ALERTS_ENABLED", "0")


# What OpenBLAS (numpy's and scipy's) reads for its thread count, in the order it reads them.
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")


def one_blas_thread(env: MutableMapping[str, str] = os.environ) -> None:
    """Run numpy's and scipy's BLAS in the calling thread only, in this command's processes.

    The command's parallelism is processes (`--jobs`); its matrices are small (a 3x3 fit, a
    triangle's barycentrics), where BLAS's own threads never pay. They cost: each OpenBLAS (numpy
    and scipy ship one each) starts a thread per further CPU when it loads, and after every call
    those threads spin for a while before they sleep. On 2 CPUs a process that made one BLAS call
    and then waited used 0.1 s of CPU in the next 0.5 s, taken from the measuring or foot-skate
    workers beside it (perf on a cold 1,000-clip `--jobs 2` build: 1.2 % of all CPU in
    `blas_thread_server`). Set before numpy loads; a thread count the user set (for OpenBLAS or
    OpenMP) is kept. Only the command line does this, as with `fork_safe_usd`."""
    if not any(name in env for name in BLAS_THREAD_VARIABLES):
        env["OPENBLAS_NUM_THREADS"] = "1"


def own_process(env: MutableMapping[str, str] = os.environ) -> None:
    """The thread settings of a process the command owns (the command line's, the build server's):
    see `fork_safe_usd` and `one_blas_thread`. Before usd-core and numpy load."""
    fork_safe_usd(env)
    one_blas_thread(env)


THREAD_VARIABLES = ("PXR_WORK_THREAD_LIMIT", *BLAS_THREAD_VARIABLES)


def thread_settings(env: Mapping[str, str]) -> dict[str, str]:
    """The thread counts a command started with environment ``env`` computes with (`own_process`
    applied to it). usd-core and BLAS fix theirs when they load, so the build server serves a
    command only when the caller's settings are the server's."""
    applied = {name: env[name] for name in THREAD_VARIABLES if name in env}
    own_process(applied)
    return {name: applied[name] for name in THREAD_VARIABLES if name in applied}


def auto_jobs() -> int:
    """`--jobs auto`: the usable CPUs on Linux, where workers are forked from the command with its
    modules loaded; 1 elsewhere, where each worker is a new Python that imports numpy, scipy and
    usd-core again (about a second each) before it measures anything: there `--jobs N` pays off
    for big libraries only, so the user asks for it."""
    return usable_cpus() if sys.platform.startswith("linux") else 1


# Local processes per usable CPU a command starts at most (`--jobs`, `index --workers`): measuring
# is CPU-bound, so more only takes memory (60-200 MB each): `index --workers 1000` on 2 CPUs
# started a thousand processes and ran the machine out of memory.
PROCESSES_PER_CPU = 4


def capped_processes(asked: int, option: str) -> int:
    """``asked`` local processes, at most `PROCESSES_PER_CPU` per usable CPU (saying so on stderr
    when it caps)."""
    cpus = usable_cpus()
    most = PROCESSES_PER_CPU * cpus
    if asked <= most:
        return asked
    sys.stderr.write(
        f"blendspace: {option} {asked} is more than {PROCESSES_PER_CPU} processes per CPU here "
        f"({cpus} CPU{'s' if cpus != 1 else ''}): using {most}\n"
    )
    return most


def usable_cpus(root: Path = Path("/")) -> int:
    """The CPUs this process can run on, at least 1: its affinity mask, capped by the CPU quota of
    its cgroups (v2 `cpu.max`, v1 `cpu.cfs_quota_us`; a quota of 1.5 CPUs counts as 2).
    ``root``: where `/proc` and `/sys` are (tests give a folder laid out like them)."""
    try:
        count = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        count = os.cpu_count() or 1
    quota = cgroup_cpu_quota(root)
    if quota is not None:
        count = min(count, math.ceil(quota))
    return max(1, count)


def cgroup_cpu_quota(root: Path = Path("/")) -> float | None:
    """The smallest CPU quota (in CPUs) of this process's cgroup and its ancestors, v1 or v2;
    None where there is none, or no cgroup file system to read (not Linux)."""
    try:
        memberships = (root / "proc/self/cgroup").read_text(encoding="utf-8").splitlines()
        mounts = (root / "proc/self/mountinfo").read_text(encoding="utf-8").splitlines()
    except OSError:
        return None
    quotas = []
    for folder in _cgroup_folders(root, memberships, mounts):
        quota = _quota_in(folder)
        if quota is not None:
            quotas.append(quota)
    return min(quotas) if quotas else None


def _cgroup_folders(root: Path, memberships: list[str], mounts: list[str]) -> list[Path]:
    """The folders of this process's CPU cgroups and of their ancestors up to each mount point."""
    v2_path, v1_path = None, None
    for line in memberships:  # "0::/path" (v2) or "4:cpu,cpuacct:/path" (v1)
        number, _, rest = line.partition(":")
        controllers, _, path = rest.partition(":")
        if number == "0" and not controllers:
            v2_path = path
        elif "cpu" in controllers.split(","):
            v1_path = path
    folders = []
    for line in mounts:
        # "36 35 98:0 ROOT MOUNT_POINT OPTIONS [optional...] - FSTYPE SOURCE SUPER_OPTIONS"
        before, _, after = line.partition(" - ")
        fields, tail = before.split(), after.split()
        if len(fields) < 5 or len(tail) < 3:
            continue
        mount_root, mount_point, fstype = _unescaped(fields[3]), _unescaped(fields[4]), tail[0]
        if fstype == "cgroup2" and v2_path is not None:
            path = v2_path
        elif fstype == "cgroup" and v1_path is not None and "cpu" in tail[2].split(","):
            path = v1_path
        else:
            continue
        # In a container the mount's root is the container's own cgroup ("/" with a cgroup
        # namespace, "/docker/<id>" without): the membership path is relative to it. A mount of
        # another part of the tree does not hold this process's cgroup.
        if mount_root != "/":
            if path != mount_root and not path.startswith(mount_root + "/"):
                continue
            path = path[len(mount_root) :]
        base = root / mount_point.lstrip("/")
        folder = base / path.lstrip("/")
        while True:
            folders.append(folder)
            if folder == base or base not in folder.parents:
                break
            folder = folder.parent
    return folders


def _unescaped(field: str) -> str:
    """A mountinfo path field: the kernel writes space, tab, newline and backslash as octal escapes."""
    return re.sub(r"\\([0-7]{3})", lambda found: chr(int(found.group(1), 8)), field)


def _quota_in(folder: Path) -> float | None:
    try:
        text = (folder / "cpu.max").read_text(encoding="utf-8").split()  # "max 100000" or "150000 100000"
        if len(text) == 2 and text[0] != "max":
            return _ratio(text[0], text[1])
    except OSError:
        pass
    try:
        quota = (folder / "cpu.cfs_quota_us").read_text(encoding="utf-8").strip()  # -1: no quota
        period = (folder / "cpu.cfs_period_us").read_text(encoding="utf-8").strip()
    except OSError:
        return None
    return _ratio(quota, period)


def _ratio(quota: str, period: str) -> float | None:
    try:
        value, length = int(quota), int(period)
    except ValueError:
        return None
    if value <= 0 or length <= 0:
        return None
    return value / length
