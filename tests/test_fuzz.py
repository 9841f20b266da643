"""Fuzzing `blendspace check` with hypothesis: random manifests, mutated BVH files and mutated
glTF documents. Whatever the input, the command exits 0, 1 or 2 (never 3, an internal error),
within `HANG_SECONDS`, and prints no traceback.

The CI run is short: `BLENDSPACE_FUZZ_EXAMPLES` examples per target (default 100, so 300 in all).
The long run, documented in README ("Trust model and limits"), is

    BLENDSPACE_FUZZ_EXAMPLES=34000 nice -n 19 python -m pytest -q tests/test_fuzz.py -p no:cacheprovider

(3 targets x 34,000 = 102,000 cases). Measured so far (README): 132,049 cases in rounds of 400
per target, three crashes found and fixed, no hang; then 104,200 cases on the fixed code with no
exit 3 and no hang. Each target also writes its tally of exit codes to
`BLENDSPACE_FUZZ_REPORT` when that is set.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import random
import signal
import tempfile
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from blendspace_pipeline.cli import main
from blendspace_pipeline.motion.procedural import GaitSpec, generate
from blendspace_pipeline.writers.bvh import write_bvh_clip
from blendspace_pipeline.writers.gltf import write_gltf_clip

EXAMPLES = int(os.environ.get("BLENDSPACE_FUZZ_EXAMPLES", "100"))
HANG_SECONDS = 60
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=EXAMPLES <= 100,  # CI: the same cases every run; long runs explore
    suppress_health_check=list(HealthCheck),
    database=None,
)
TALLY: Counter[str] = Counter()


class Hang(Exception):
    pass


@contextlib.contextmanager
def _time_limit(seconds: int) -> Iterator[None]:
    def alarm(signum: int, frame: object) -> None:
        raise Hang(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@pytest.fixture(scope="module")
def assets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("fuzz-assets")
    os.environ.setdefault("BLENDSPACE_CACHE_DIR", str(folder / "cache"))  # good clips measure once
    bvh = folder / "walk.bvh"
    write_bvh_clip(generate(GaitSpec("walk", speed=1.4)), bvh)
    turn = folder / "turn.bvh"
    write_bvh_clip(generate(GaitSpec("turn", turn_rate=90.0)), turn)
    idle = folder / "idle.bvh"
    write_bvh_clip(generate(GaitSpec("idle")), idle)
    gltf = folder / "g.gltf"
    write_gltf_clip(generate(GaitSpec("walk", speed=1.4)), gltf)
    return {
        "walk": bvh.read_text(encoding="utf-8"),
        "turn": turn.read_bytes(),
        "idle": idle.read_bytes(),
        "gltf": json.loads(gltf.read_text(encoding="utf-8")),
    }


def _check(root: Path, manifest: Path) -> None:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _time_limit(HANG_SECONDS):
        code = main(["check", str(manifest)])
    TALLY[f"exit {code}"] += 1
    if sum(TALLY.values()) % 250 == 0:
        _write_report()  # a long run stopped by a time limit still leaves its count
    text = out.getvalue() + err.getvalue()
    assert code in (0, 1, 2), f"exit {code}\n{text}\n--- manifest ---\n{manifest.read_text(errors='replace')}"
    assert "Traceback" not in text


def _project(assets: dict[str, Any], folder: Path) -> None:
    clips = folder / "clips"
    clips.mkdir(parents=True)
    (clips / "turn.bvh").write_bytes(assets["turn"])
    (clips / "idle.bvh").write_bytes(assets["idle"])


def _write_report() -> None:
    target = os.environ.get("BLENDSPACE_FUZZ_REPORT")
    if target:
        Path(target).write_text(json.dumps(dict(TALLY), indent=2) + "\n", encoding="utf-8")


@pytest.fixture(scope="module", autouse=True)
def _report() -> Iterator[None]:
    yield
    _write_report()


# -- manifests ------------------------------------------------------------------------------------

NUMBERS = st.one_of(
    st.integers(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1, 10**1000, 2**63, 1e308, -1e308, 1e-300, 0.5, 100, 180, -180]),
)
TEXT = st.one_of(
    st.text(max_size=30), st.sampled_from(["auto", "m", "cm", "y", "z", "x", "../../x_left", ""])
)
SCALAR = st.one_of(NUMBERS, TEXT, st.booleans(), st.none())
VALUE = st.recursive(
    SCALAR,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(TEXT, inner, max_size=4)),
    max_leaves=12,
)
PATHS = st.sampled_from(
    [
        "clips/*.bvh",
        "clips/walk.bvh",
        "clips/**/*.bvh",
        "clips",
        "",
        "../x.bvh",
        "/dev/zero",
        "/etc/passwd",
        "clips/" + "a" * 300 + ".bvh",
        "clips/[.bvh",
        "clips\\walk.bvh",
    ]
)
ENTRY = st.fixed_dictionaries(
    {"path": st.one_of(PATHS, SCALAR)},
    optional={
        "name": st.one_of(TEXT, SCALAR),
        "range": st.one_of(st.lists(NUMBERS, min_size=2, max_size=2), SCALAR),
        "position": st.lists(NUMBERS, min_size=2, max_size=2),
        "skeleton": st.dictionaries(st.sampled_from(["units", "up", "root", "mirror"]), SCALAR, max_size=2),
        "ignore": VALUE,
    },
)
AXIS = st.fixed_dictionaries(
    {
        "feature": st.sampled_from(["speed", "turn_rate", "direction", "wobble"]),
        "min": NUMBERS,
        "max": NUMBERS,
        "divisions": NUMBERS,
    }
)
MANIFEST = st.fixed_dictionaries(
    {
        "schema_version": st.one_of(st.just(1), SCALAR),
        "name": st.one_of(st.just("t"), TEXT),
        "clips": st.one_of(st.lists(ENTRY, min_size=1, max_size=4), VALUE),
    },
    optional={
        "axes": st.fixed_dictionaries({}, optional={"x": AXIS, "y": AXIS}),
        "skeleton": st.dictionaries(st.sampled_from(["units", "up", "root", "left_hip", "mirror"]), SCALAR),
        "thresholds": st.dictionaries(st.sampled_from(["too_close", "acute_angle", "misalignment"]), NUMBERS),
        "fixes": st.dictionaries(
            st.sampled_from(["mirror", "axis_clips", "too_close", "straighten"]), SCALAR
        ),
        "rules": VALUE,
        "layers": VALUE,
        "output": VALUE,
        "extra": VALUE,
    },
)


@FUZZ
@given(document=MANIFEST)
def test_fuzzed_manifests_never_crash(assets: dict[str, Any], document: dict[str, Any]) -> None:
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        _project(assets, root)
        (root / "clips" / "walk.bvh").write_text(assets["walk"], encoding="utf-8")
        manifest = root / "manifest.yaml"
        # JSON is YAML: every value the strategy makes (huge ints, nan) reaches the loader as typed.
        manifest.write_text(json.dumps(document, allow_nan=True, default=str), encoding="utf-8")
        _check(root, manifest)


# -- BVH ------------------------------------------------------------------------------------------

TOKENS = st.one_of(
    NUMBERS.map(str),
    st.sampled_from(
        ["{", "}", "JOINT", "End", "Site", "CHANNELS", "OFFSET", "MOTION", "Frames:", "\ufeff", ""]
    ),
    st.text(max_size=8),
)


@st.composite
def mutated_bvh(draw: st.DrawFn, text: str) -> bytes:
    lines = text.split("\n")
    for _ in range(draw(st.integers(min_value=1, max_value=4))):
        kind = draw(st.sampled_from(["token", "delete", "duplicate", "truncate", "bytes", "frames"]))
        index = draw(st.integers(min_value=0, max_value=len(lines) - 1))
        if kind == "token":
            words = lines[index].split() or [""]
            words[draw(st.integers(min_value=0, max_value=len(words) - 1))] = draw(TOKENS)
            lines[index] = " ".join(words)
        elif kind == "delete" and len(lines) > 1:
            del lines[index]
        elif kind == "duplicate":
            lines.insert(index, lines[index])
        elif kind == "truncate":
            lines = lines[: index + 1]
        elif kind == "frames":
            lines = [f"Frames: {draw(NUMBERS)}" if line.startswith("Frames") else line for line in lines]
        else:
            lines[index] += draw(st.binary(max_size=8)).decode("latin-1")
    return "\n".join(lines).encode("utf-8", errors="surrogateescape")


@FUZZ
@given(data=st.data())
def test_fuzzed_bvh_files_never_crash(assets: dict[str, Any], data: st.DataObject) -> None:
    clip = data.draw(mutated_bvh(assets["walk"]))
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        _project(assets, root)
        (root / "clips" / "walk.bvh").write_bytes(clip)
        manifest = root / "manifest.yaml"
        manifest.write_text("schema_version: 1\nname: t\nclips:\n  - path: clips/*.bvh\n", encoding="utf-8")
        _check(root, manifest)


# -- glTF -----------------------------------------------------------------------------------------


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    found = [prefix]
    if isinstance(node, dict):
        for key, value in node.items():
            found += _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for index, value in enumerate(node[:6]):
            found += _paths(value, (*prefix, index))
    return found


@FUZZ
@given(data=st.data())
def test_fuzzed_gltf_documents_never_crash(assets: dict[str, Any], data: st.DataObject) -> None:
    document = json.loads(json.dumps(assets["gltf"]))
    paths = _paths(document)
    for _ in range(data.draw(st.integers(min_value=1, max_value=3))):
        path = data.draw(st.sampled_from(paths[1:]))
        parent = document
        try:
            for key in path[:-1]:
                parent = parent[key]
            parent[path[-1]] = data.draw(
                st.one_of(VALUE, NUMBERS, st.sampled_from(["../../etc/passwd", "/dev/zero"]))
            )
        except (KeyError, IndexError, TypeError):
            continue
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        _project(assets, root)
        text = json.dumps(document, allow_nan=True, default=str)
        if data.draw(st.booleans()):
            cut = data.draw(st.integers(min_value=0, max_value=len(text)))
            text = text[:cut] if random.Random(cut).random() < 0.5 else text
        (root / "clips" / "walk.gltf").write_text(text, encoding="utf-8")
        manifest = root / "manifest.yaml"
        manifest.write_text(
            "schema_version: 1\nname: t\nclips:\n  - path: clips/*.bvh\n  - path: clips/walk.gltf\n",
            encoding="utf-8",
        )
        _check(root, manifest)
