"""One clip edited through the build server, this checkout against another revision, paired.

    python benchmarks/bench_edit_ab.py BASE_REV [--rounds 30] [--clips 1000] [--jobs 2] [--library DIR]

On a 2-vCPU machine the host's speed moves a served edit by 20-40 % within an hour, more than
most changes to the edit path are worth, so two `bench_server.py` runs minutes apart cannot tell
a 50 ms change from noise. This runs both versions in the same minutes instead:
- `BASE_REV` is checked out in a temporary git worktree, its kernels built in place, and both
  versions' bytecode compiled (as an installed tool has it, see `installed.py`);
- each version gets its own copy of one generated library (`bench_rebuild.write_library`), its own
  cache and its own running build server (`PYTHONPATH` picks the version);
- every round edits the same clip to the same new speed in both copies and times
  `blendspace build --no-fix --jobs N` in each, the versions taking turns at going first (whoever
  goes first was about 15 ms slower on this machine, an order bias a fixed order would report as a
  difference).
Printed: each version's median, mean and best, and the paired difference (this checkout minus the
base, per round: median and mean), with the host's speed before and after (`host_speed`).
Nothing is asserted; on a shared machine run it alone.
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_rebuild import write_library
from bench_server import host_speed
from installed import compile_package

from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip

REPO = Path(__file__).resolve().parents[1]
BLENDSPACE = [sys.executable, "-m", "blendspace_pipeline"]


def _checked(
    command: list[str], cwd: Path | None = None, env: dict[str, str] | None = None, ok: tuple[int, ...] = (0,)
) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(command, capture_output=True, text=True, check=False, cwd=cwd, env=env)
    if done.returncode not in ok:
        raise SystemExit(f"{' '.join(command)} exited {done.returncode}:\n{done.stderr[-2000:]}")
    return done


# The base's kernels are built from its own `setup.py` (its extensions and compiler flags), without
# the rest of the project's configuration: the build environment's setuptools may not read it.
_BUILD_KERNELS = """
import setuptools
from setuptools.command.build_ext import build_ext
found = {}
setuptools.setup = lambda **options: found.update(options)
exec(open("setup.py", encoding="utf-8").read())
command = build_ext(setuptools.Distribution({"ext_modules": found["ext_modules"]}))
command.inplace = True
command.ensure_finalized()
command.run()
"""


def _base_checkout(rev: str, folder: Path) -> Path:
    """``rev`` in a worktree at ``folder``, its kernels built in place and its bytecode compiled.
    (Without its own kernels the editable install's finder would hand it this checkout's.)"""
    _checked(["git", "-C", str(REPO), "worktree", "add", "--detach", str(folder), rev])
    _checked([sys.executable, "-c", _BUILD_KERNELS], cwd=folder)
    _checked([sys.executable, "-m", "compileall", "-q", "blendspace_pipeline", "rules"], cwd=folder)
    return folder


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("base", metavar="BASE_REV", help="the revision to compare with (e.g. HEAD~3)")
    parser.add_argument("--rounds", type=int, default=30)
    parser.add_argument("--clips", type=int, default=1000)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument(
        "--library", type=Path, help="a folder of BVH clips to copy instead of a generated library"
    )
    args = parser.parse_args()
    compile_package()  # this checkout's bytecode
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        base = _base_checkout(args.base, root / "base-checkout")
        try:
            _compare(root, {"this checkout": REPO, f"base {args.base}": base}, args)
        finally:
            _checked(["git", "-C", str(REPO), "worktree", "remove", "--force", str(base)])


def _compare(root: Path, versions: dict[str, Path], args: argparse.Namespace) -> None:
    if args.library is not None:
        library = sorted(args.library.glob("*.bvh"))
        if not library:
            raise SystemExit(
                f"--library {args.library}: no .bvh files in that folder (give the clips' folder)"
            )
    else:
        library = write_library(root / "library", args.clips, 7.0)
    environment = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "BLENDSPACE_NO_SERVER")}
    envs: dict[str, dict[str, str]] = {}
    manifests: dict[str, Path] = {}
    for index, (name, code) in enumerate(versions.items()):
        project = root / f"project{index}"
        shutil.copytree(library[0].parent, project / "clips")
        manifests[name] = project / "manifest.yaml"
        manifests[name].write_text(
            "schema_version: 1\nname: library\nclips:\n  - path: clips/*.bvh\n"
            "output: {formats: [json, usd, html, png]}\n",
            encoding="utf-8",
        )
        envs[name] = {
            **environment,
            "PYTHONPATH": str(code),
            "BLENDSPACE_CACHE_DIR": str(project / "cache"),
            "BLENDSPACE_SERVER_DIR": str(project / "server"),
        }
    build = ["build", "--no-fix", "--jobs", str(args.jobs)]
    names = list(versions)
    times: dict[str, list[float]] = {name: [] for name in names}
    speed_before = host_speed(library)
    try:
        for name in names:  # cold, without the server: fills each version's cache
            local = {**envs[name], "BLENDSPACE_NO_SERVER": "1"}
            _checked([*BLENDSPACE, *build, str(manifests[name])], env=local, ok=(0, 1))
            _checked([*BLENDSPACE, "server", "start"], env=envs[name])
        choose = random.Random(7)
        for round_ in range(args.rounds):
            clip = choose.choice(library).name
            speed = 1.5 + 1.5 * choose.random()
            for name in names[round_ % len(names) :] + names[: round_ % len(names)]:
                path = manifests[name].parent / "clips" / clip
                write_bvh_clip(
                    generate(GaitSpec(Path(clip).stem, speed=speed, duration=7.0, fps=120.0)), path
                )
                start = time.perf_counter()
                _checked([*BLENDSPACE, *build, str(manifests[name])], env=envs[name], ok=(0, 1))
                times[name].append(time.perf_counter() - start)
    finally:
        for name in names:
            subprocess.run([*BLENDSPACE, "server", "stop"], capture_output=True, env=envs[name], check=False)
    speed_after = host_speed(library)
    print(f"{len(library)} clips, one clip edited, build --no-fix --jobs {args.jobs} through the server")
    print(
        f"host speed (read + measure one clip, CPU): {speed_before:.2f} ms before, {speed_after:.2f} ms after"
    )
    for name in names:
        walls = times[name]
        print(
            f"{name:<28} median {statistics.median(walls):.3f}s  mean {statistics.mean(walls):.3f}s  "
            f"best {min(walls):.3f}s  ({len(walls)} edits)"
        )
    paired = [a - b for a, b in zip(times[names[0]], times[names[1]], strict=True)]
    print(
        f"{'paired, this minus base':<28} median {1000 * statistics.median(paired):+.0f} ms  "
        f"mean {1000 * statistics.mean(paired):+.0f} ms"
    )


if __name__ == "__main__":
    main()
