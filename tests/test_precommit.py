"""The `blendspace-check` pre-commit hook, run for real with `pre-commit try-repo`.

`try-repo` clones the hook repository, installs it into a fresh virtualenv with pip (language:
python), and runs the hook on a studio's asset repository. The hook repository here is a
committed snapshot of this working tree made in a temporary folder. That way the test covers
exactly the code being changed, and this checkout's git state is never touched. Installing
needs the package index for the dependencies. When the index cannot be reached, or the install
takes longer than `TIMEOUT` seconds, the try-repo tests are skipped with the reason. The hook's
entry command is also run directly, the way pre-commit would run it, and that needs no network.
A try-repo run takes about 15 s on the development machine, almost all of it the pip install.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import tidy_set
from ruamel.yaml import YAML

from blendspace_pipeline.motion.procedural import generate
from blendspace_pipeline.writers.usd_clip import write_usd_clip

REPO = Path(__file__).resolve().parents[1]
HOOK_ID = "blendspace-check"
TIMEOUT = 300  # seconds for one try-repo run (virtualenv + pip install + hook)
# pip's messages when the package index is out of reach (not when the package is broken).
OFFLINE = (
    "Failed to establish a new connection",
    "Temporary failure in name resolution",
    "Network is unreachable",
    "NewConnectionError",
    "ProxyError",
    "No matching distribution found",
)

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")

SPECS = tidy_set()
GOOD = list(SPECS)  # warnings and infos only
BAD = ["idle", "walk_left", "walk_right"]  # the walks' edge crosses turn_rate = 0: an error


def git(*args: str, cwd: Path) -> str:
    """Run git with a fixed identity, so commits work on machines without a git config."""
    done = subprocess.run(
        [
            "git",
            "-c", "user.name=blendspace tests",
            "-c", "user.email=tests@blendspace.invalid",
            "-c", "commit.gpgsign=false",
            "-c", "init.defaultBranch=main",
            *args,
        ],
        cwd=cwd,
        capture_output=True,
        text=True,
        check=True,
    )  # fmt: skip
    return done.stdout


@pytest.fixture(scope="module")
def hook_repo(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """This working tree (tracked and new files, not ignored ones), committed in a new repository."""
    listing = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        capture_output=True,
        check=False,
    )
    if listing.returncode != 0:
        pytest.skip(f"{REPO} is not a git checkout: {listing.stderr.decode(errors='replace').strip()}")
    target = tmp_path_factory.mktemp("hook-repo")
    for name in filter(None, listing.stdout.decode().split("\0")):
        source = REPO / name
        if source.is_file():  # a file deleted in the working tree stays listed until staged
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)
    git("init", "-q", cwd=target)
    git("add", "-A", cwd=target)
    git("commit", "-q", "-m", "working tree snapshot", cwd=target)
    return target


def asset_repo(root: Path, clips: list[str]) -> Path:
    """A studio's asset repository: clips, a manifest and a YAML file that is not a manifest."""
    root.mkdir(parents=True)
    (root / "clips").mkdir()
    for name in clips:
        path = root / "clips" / f"{name}.usda"
        write_usd_clip(generate(SPECS[name], source=path), path, meters_per_unit=1.0, up_axis="y")
    entries = "".join(f"  - path: clips/{name}.usda\n" for name in clips)
    (root / "locomotion.manifest.yaml").write_text(
        f"schema_version: 1\nname: locomotion\nclips:\n{entries}", encoding="utf-8"
    )
    # The hook's `files:` pattern must not hand this to `blendspace check` (it would exit 2).
    (root / "ci.yaml").write_text("stages: [lint, test]\n", encoding="utf-8")
    git("init", "-q", cwd=root)
    git("add", "-A", cwd=root)
    return root


def try_repo(hook: Path, assets: Path, home: Path) -> tuple[subprocess.CompletedProcess[str], float]:
    env = {**os.environ, "PRE_COMMIT_HOME": str(home), "PRE_COMMIT_COLOR": "never"}
    command = [sys.executable, "-m", "pre_commit", "try-repo", str(hook), HOOK_ID, "--all-files", "--verbose"]
    start = time.perf_counter()
    try:
        done = subprocess.run(
            command, cwd=assets, env=env, capture_output=True, text=True, timeout=TIMEOUT, check=False
        )
    except subprocess.TimeoutExpired:
        pytest.skip(f"pre-commit try-repo took longer than {TIMEOUT} s (slow package index?)")
    seconds = time.perf_counter() - start
    print(f"pre-commit try-repo {HOOK_ID}: {seconds:.1f} s")
    log = home / "pre-commit.log"
    details = log.read_text(encoding="utf-8", errors="replace") if log.exists() else ""
    if done.returncode == 3 and any(marker in details + done.stdout for marker in OFFLINE):
        pytest.skip(
            f"pre-commit could not install the hook: the package index is out of reach\n{details[-2000:]}"
        )
    assert "An unexpected error has occurred" not in done.stdout, done.stdout + details
    return done, seconds


def test_try_repo_passes_a_good_manifest(hook_repo: Path, tmp_path: Path) -> None:
    assets = asset_repo(tmp_path / "assets", GOOD)
    before = git("status", "--porcelain", "--untracked-files=all", cwd=assets)
    done, _ = try_repo(hook_repo, assets, tmp_path / "pre-commit-home")
    output = done.stdout + done.stderr
    assert done.returncode == 0, output
    assert re.search(r"^blendspace check\.+Passed$", done.stdout, flags=re.M), output
    assert "checked 1 manifest(s): 0 errors" in output  # the hook ran on the manifest alone
    assert "ci.yaml" not in output
    # `check` wrote nothing into the repository.
    assert git("status", "--porcelain", "--untracked-files=all", cwd=assets) == before


def test_try_repo_fails_on_an_error_diagnostic(hook_repo: Path, tmp_path: Path) -> None:
    assets = asset_repo(tmp_path / "assets", BAD)
    done, _ = try_repo(hook_repo, assets, tmp_path / "pre-commit-home")
    output = done.stdout + done.stderr
    assert done.returncode == 1, output
    assert re.search(r"^blendspace check\.+Failed$", done.stdout, flags=re.M), output
    assert re.search(
        r"^locomotion\.manifest\.yaml:5:5: error crossing-axis: edge walk_left - walk_right crosses",
        output,
        flags=re.M,
    ), output


# -- the hook definition and its entry command, without pre-commit ---------------------------------


def hook_definition() -> dict[str, Any]:
    hooks = YAML(typ="safe").load((REPO / ".pre-commit-hooks.yaml").read_text(encoding="utf-8"))
    [hook] = [h for h in hooks if h["id"] == HOOK_ID]
    return dict(hook)


def test_hook_definition() -> None:
    hook = hook_definition()
    assert hook["language"] == "python" and hook["entry"] == "blendspace check --changed"
    assert hook.get("pass_filenames", True) and hook["require_serial"]
    assert "--no-plugins" in hook["description"]  # the trust model is stated where users look
    files = re.compile(hook["files"])
    # Manifests, layer manifests (any YAML: `check --changed` skips YAML that is not a manifest)
    # and clip files: a commit that changes only a clip must still check the space.
    for name in (
        "locomotion.manifest.yaml",
        "anim/walk.blendspace.yml",
        "lateral.yaml",
        "clips/walk.usda",
        "clips/run.BVH",
        "clips/turn.glb",
        "clips/turn.bin",
    ):
        assert files.search(name), name
    for name in ("README.md", "manifest.yaml.bak", "clips/notes.txt", "textures/a.png"):
        assert not files.search(name), name


def entry_command() -> list[str]:
    """The hook's entry as pre-commit runs it: the `blendspace` console script of the install."""
    program, *args = hook_definition()["entry"].split()
    script = shutil.which(
        program, path=os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]])
    )
    return [script, *args] if script else [sys.executable, "-m", "blendspace_pipeline", *args]


def run_entry(assets: Path, *names: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*entry_command(), *names], cwd=assets, capture_output=True, text=True, timeout=120, check=False
    )


def test_a_changed_clip_checks_the_manifest_that_uses_it(tmp_path: Path) -> None:
    assets = asset_repo(tmp_path / "assets", BAD)
    done = run_entry(assets, "clips/walk_left.usda")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "locomotion.manifest.yaml:5:5: error crossing-axis" in done.stdout
    # A file no manifest reads checks nothing and passes.
    (assets / "other.usda").write_text("#usda 1.0\n", encoding="utf-8")
    done = run_entry(assets, "other.usda", "ci.yaml")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "nothing to check" in done.stdout


def test_a_changed_layer_manifest_checks_its_parent(tmp_path: Path) -> None:
    assets = asset_repo(tmp_path / "assets", GOOD)
    main = assets / "locomotion.manifest.yaml"
    main.write_text(
        main.read_text(encoding="utf-8") + "layers:\n  - {name: side, kind: beta, manifest: lateral.yaml}\n",
        encoding="utf-8",
    )
    # The layer manifest names a clip that does not exist: only checking through the parent (or
    # the layer itself) can find that, and the parent must be the one reported.
    (assets / "lateral.yaml").write_text(
        "schema_version: 1\nname: lateral\nclips:\n  - path: clips/missing.usda\n", encoding="utf-8"
    )
    done = run_entry(assets, "lateral.yaml")
    assert done.returncode == 2, done.stdout + done.stderr
    assert "lateral.yaml:4:" in done.stderr and "missing.usda" in done.stderr


def run_like_pre_commit(assets: Path) -> subprocess.CompletedProcess[str]:
    """The entry with the tracked files that `files:` selects appended, as pre-commit passes them."""
    files = re.compile(hook_definition()["files"])
    tracked = git("ls-files", cwd=assets).split()
    chosen = [name for name in tracked if files.search(name)]
    assert "locomotion.manifest.yaml" in chosen and "ci.yaml" in chosen
    return subprocess.run(
        [*entry_command(), *chosen], cwd=assets, capture_output=True, text=True, timeout=120, check=False
    )


def test_entry_command_on_a_good_manifest(tmp_path: Path) -> None:
    done = run_like_pre_commit(asset_repo(tmp_path / "assets", GOOD))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "checked 1 manifest(s): 0 errors" in done.stdout


def test_entry_command_on_a_bad_manifest(tmp_path: Path) -> None:
    done = run_like_pre_commit(asset_repo(tmp_path / "assets", BAD))
    assert done.returncode == 1, done.stdout + done.stderr
    assert "locomotion.manifest.yaml:5:5: error crossing-axis: edge walk_left - walk_right" in done.stdout


def test_changed_files_map_to_the_manifests_that_read_them(tmp_path: Path) -> None:
    from blendspace_pipeline.commands._changed import manifests_for
    from blendspace_pipeline.writers.gltf import write_gltf_clip

    assets = asset_repo(tmp_path / "assets", GOOD)
    clips = assets / "clips"
    write_gltf_clip(generate(SPECS["idle"]), clips / "extra.gltf")
    (clips / "extra.bin").write_bytes(b"\0" * 8)  # a separate buffer's name, as Blender writes it
    other = assets / "other" / "second.yaml"
    other.parent.mkdir()
    other.write_text(
        "schema_version: 1\nname: second\nclips:\n  - path: ../clips/extra.gltf\n", encoding="utf-8"
    )
    main_manifest = assets / "locomotion.manifest.yaml"

    def chosen(*names: str) -> list[str]:
        return sorted(p.name for p in manifests_for([assets / n for n in names], assets))

    assert chosen("clips/extra.bin") == ["second.yaml"]
    assert chosen("clips/walk_left.usda") == [main_manifest.name]
    assert chosen("clips/walk_left.usda", "clips/extra.gltf") == [main_manifest.name, "second.yaml"]
    assert chosen("ci.yaml", "README.md") == []


def test_a_deleted_clip_selects_the_manifests_that_named_it(tmp_path: Path) -> None:
    """`check --changed clips/walk_left.usda` after deleting it said "no manifest uses the changed
    files" (exit 0); a plain `check` of the manifest is exit 2 ("not found"). A deleted file
    selects the manifests whose entries name it, explicitly or by a glob, and so `check` fails."""
    from blendspace_pipeline.commands._changed import manifests_for

    assets = asset_repo(tmp_path / "assets", GOOD)
    globbed = assets / "globbed.yaml"
    globbed.write_text("schema_version: 1\nname: g\nclips:\n  - path: clips/*.usda\n", encoding="utf-8")
    elsewhere = assets / "elsewhere.yaml"
    elsewhere.write_text("schema_version: 1\nname: e\nclips:\n  - path: other/*.usda\n", encoding="utf-8")
    (assets / "clips" / "walk_left.usda").unlink()
    names = sorted(p.name for p in manifests_for([assets / "clips" / "walk_left.usda"], assets))
    assert names == ["globbed.yaml", "locomotion.manifest.yaml"]
    # A file whose name has glob characters is named by itself too (fnmatch reads `[1]` as a class).
    literal = assets / "literal.yaml"
    literal.write_text(
        "schema_version: 1\nname: l\nclips:\n  - path: 'takes/walk[1].usda'\n", encoding="utf-8"
    )
    assert [p.name for p in manifests_for([assets / "takes" / "walk[1].usda"], assets)] == ["literal.yaml"]
    code = subprocess.run(
        [sys.executable, "-m", "blendspace_pipeline", "check", "--changed", "clips/walk_left.usda"],
        cwd=assets,
        env={**os.environ, "BLENDSPACE_NO_SERVER": "1", "BLENDSPACE_CACHE_DIR": str(tmp_path / "cache")},
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )
    assert code.returncode == 2, code.stdout + code.stderr
    assert "walk_left.usda" in code.stderr and "not found" in code.stderr


def test_the_hook_fires_on_every_clip_format_the_tool_reads() -> None:
    """The hook's `files:` pattern left FBX out, a documented clip format."""
    import re

    import yaml  # pre-commit's own dependency

    from blendspace_pipeline.readers import supported_suffixes

    hook = yaml.safe_load(
        (Path(__file__).parent.parent / ".pre-commit-hooks.yaml").read_text(encoding="utf-8")
    )
    pattern = re.compile(hook[0]["files"])
    for suffix in supported_suffixes():
        assert pattern.search(f"clips/walk{suffix}"), suffix
        assert pattern.search(f"clips/WALK{suffix.upper()}"), suffix
    assert pattern.search("locomotion.yaml") and not pattern.search("README.md")
