"""`build`: analyse, then publish every output as one set.

Generation folders (readers of the documents see the old set or the new set, never a mix):

    OUT/N.blendspace.json          -> .blendspace/N/current/N.blendspace.json   (stable symlinks)
    OUT/.blendspace/N/current      -> g-<content hash>                            (the one pointer)
    OUT/.blendspace/N/g-<hash>/    the files of one build (documents and generated clips)
    OUT/clips/walk_mirror.usda     a real file (hard link into the generation, else a copy)

1. Every output is written into `OUT/.blendspace-staging-<pid>-<random>/` (same file system).
2. Each file is synced and checked against its format (`report.atomic.verify_written`): a full
   disk that a library did not report is an error, never a published truncated file.
3. The staging folder is renamed to `g-<hash of its contents>` (identical builds reuse it, so a
   rebuild is byte- and path-identical), then `current` is switched by one `os.replace` of a new
   symlink: that rename is the moment the whole set changes.
   Generated clips are placed as real files just before that rename (engines import them as
   assets; Unity does not support symlinked assets, exporters resolve paths): each one is
   replaced in one rename, but the clips are not switched together with the documents.
4. The user-visible links of the documents (JSON, USD, HTML, PNG) are (re)made, links of files
   the new set no longer has are removed, and older generations are deleted.

A failure before the switch leaves the previous documents untouched (and removes a folder the
build created); only a failure between placing the clips and the switch leaves new clips beside
the previous documents. Staging folders of killed builds (their pid no longer runs) are removed by the next
build. Where symlinks cannot be made (Windows without developer mode) the files are moved into
place one by one as before.

Unchanged outputs are not written again: each document output's inputs (the document's JSON,
the format, the tool version and source files, the writing libraries' versions, the report's
date) are digested, and the record of the current generation (in the cache folder, `outputs/`,
so the output folder holds only what is published) says which digest each file was written from
and its size, mtime and SHA-256. When the digest matches and the previous file is still the one
written (same stat, or same bytes where the stat moved), it is hard-linked into the staging folder
instead of written; a deleted or hand-edited output is written again. An identical generation
that already exists gets any file that differs from this build's replaced.
"""

from __future__ import annotations

import contextlib
import errno
import filecmp
import functools
import hashlib
import json
import os
import re
import shutil
import tempfile
import time
import zlib
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from blendspace_pipeline import __version__
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.motion.file_names import safe_file_stem, unique_stems
from blendspace_pipeline.pipeline.analysis import analyse
from blendspace_pipeline.pipeline.blend_quality import blend_quality
from blendspace_pipeline.pipeline.cache import cache_dir, file_sha256, write_atomic
from blendspace_pipeline.pipeline.early_quality import EarlyQuality
from blendspace_pipeline.pipeline.fix_loop import FixState, apply_fixes
from blendspace_pipeline.pipeline.forked import Children, Task, can_fork, run_tasks
from blendspace_pipeline.pipeline.generated_clips import source_suffix, write_generated_clip
from blendspace_pipeline.pipeline.own_outputs import (
    CURRENT,
    GENERATIONS,
    PLACED,
    output_folder,
    placed_record,
    still_placed,
)
from blendspace_pipeline.pipeline.progress import Progress
from blendspace_pipeline.pipeline.to_document import SampleDocsAhead, to_document
from blendspace_pipeline.report.atomic import verify_written
from blendspace_pipeline.space.document import BlendSpaceDocument
from blendspace_pipeline.space.model import BetaSpace, BlendSpace

if TYPE_CHECKING:
    from blendspace_pipeline.report.html import ReportDraft


@dataclass
class BuildResult:
    space: BlendSpace
    document: BlendSpaceDocument
    out_dir: Path
    written: list[Path]
    fixes: FixState
    layer_fixes: dict[str, FixState] = field(default_factory=dict)  # beta layer name -> its fixes

    def generated_names(self) -> list[str]:
        """Every clip the fixes made: the main space's, then each beta layer's as `layer/clip`."""
        names = sorted(self.fixes.generated)
        for layer, state in self.layer_fixes.items():
            names += [f"{layer}/{name}" for name in sorted(state.generated)]
        return names


def output_dir(space: BlendSpace, out: Path | None) -> Path:
    return output_folder(space.manifest, out)


def _write_json(doc: BlendSpaceDocument, path: Path) -> None:
    from blendspace_pipeline.writers.blendspace_json import write_blendspace_json

    write_blendspace_json(doc, path)


def input_files(space: BlendSpace) -> list[Path]:
    """The files a build reads: its manifest, the clips, and those of its layers."""
    files = [space.manifest.path]
    files += [s.clip.source for s in space.samples if not s.generated]
    files += [Path(f) for s in space.samples if not s.generated for f in s.clip.measurement.dependencies]
    for layer in space.layer_spaces:
        if isinstance(layer, BetaSpace):
            files += input_files(layer.space)
        else:
            files += [clip.source for clip in layer.clips]
            files += [Path(f) for clip in layer.clips for f in clip.measurement.dependencies]
    return files


class _ReportParts:
    """The HTML report's clock and draft, each made once per build: the clock (newest input
    modification time: a `stat` per clip, 0.05 s on 1,000 clips) both dates the report and is
    digested among its inputs; the draft (`html.draft_report`) is drawn while the blend quality
    maps are still computed, when there is a core to spare."""

    def __init__(self, space: BlendSpace) -> None:
        self.space = space
        self.draft: ReportDraft | None = None

    @functools.cached_property
    def stamp(self) -> str:
        from blendspace_pipeline.report.html import build_stamp

        return build_stamp(input_files(self.space))

    def draw(self, document: BlendSpaceDocument) -> None:
        """Date the report and draw everything of ``document``'s report but what its blend
        quality changes (set later). A failure leaves no draft: the HTML writer then draws the
        page itself and fails in its turn, so the error shown is the one the serial order of the
        outputs gives."""
        from blendspace_pipeline.report.html import draft_report

        self.stamp  # noqa: B018 - the clock is read now, while the maps are still being made
        try:
            self.draft = draft_report(document)
        except Exception:
            self.draft = None


def _writers(report: _ReportParts) -> dict[str, tuple[str, Callable[[BlendSpaceDocument, Path], None]]]:
    """format -> (file suffix, writer); the HTML is dated and drafted by ``report``. Heavy
    writers import only when used."""

    def usd(doc: BlendSpaceDocument, path: Path) -> None:
        from blendspace_pipeline.writers.usd_blendspace import write_usd_blendspace

        write_usd_blendspace(doc, path)

    def html(doc: BlendSpaceDocument, path: Path) -> None:
        from blendspace_pipeline.report import write_html_report

        write_html_report(doc, path, stamp=report.stamp, draft=report.draft)

    def png(doc: BlendSpaceDocument, path: Path) -> None:
        from blendspace_pipeline.report import write_png

        write_png(doc, path)

    return {
        "json": (".blendspace.json", _write_json),
        "usd": (".blendspace.usda", usd),
        "html": (".report.html", html),
        "png": (".png", png),
    }


# Bumped whenever a writer would write other bytes for the same document (in a release the
# version changes too; the package's own source files are digested as well, see `_code_digest`).
OUTPUT_REVISION = 2
# Libraries whose version changes what a writer writes.
_WRITER_LIBRARIES = {"usd": ("usd-core",), "png": ("OpenImageIO", "numpy"), "html": ("numpy",), "json": ()}


def _output_inputs(name: str, file_name: str, document_digest: str, report: _ReportParts) -> str:
    """Digest of everything output ``name`` is made of: the document, the writer and its code."""
    parts: list[object] = [name, file_name, document_digest, __version__, OUTPUT_REVISION, _code_digest()]
    parts += [_library_version(library) for library in _WRITER_LIBRARIES.get(name, ())]
    if name == "html":
        parts.append(report.stamp)  # the report's one clock
    if name == "png":
        parts.append(f"zlib=={zlib.ZLIB_RUNTIME_VERSION}")  # deflates the PNG's rows (`png_file`)
    return hashlib.sha256(json.dumps(parts).encode()).hexdigest()


def warm() -> None:
    """Compute now what every build of this installed code computes alike: the code digest, the
    writer libraries' versions, the PNG's font and legend. The build server calls it once, and
    the commands it forks inherit them (about 30 ms of a served 1,000-clip build). They hold as
    long as the code does, and a server never runs a command for code that moved
    (`server.address.fingerprint`)."""
    from blendspace_pipeline.report.png import warm as warm_png

    _code_digest()
    for libraries in _WRITER_LIBRARIES.values():
        for library in libraries:
            _library_version(library)
    warm_png()


@functools.cache
def _code_digest() -> str:
    """Size and mtime of every source file of the package: a checkout of other writer code under
    the same version (a developer's tree) writes the outputs again."""
    root = Path(__file__).resolve().parent.parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        info = path.stat()
        digest.update(f"{path.relative_to(root).as_posix()}|{info.st_size}|{info.st_mtime_ns}\n".encode())
    return digest.hexdigest()


@functools.cache
def _library_version(name: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"{name}=={version(name)}"
    except PackageNotFoundError:
        return f"{name} (not installed)"


def _record_path(home: Path) -> Path | None:
    """Where the record of ``home``'s outputs lives: in the cache folder, not the output folder,
    which holds only what the build publishes (two builds' folders stay byte-identical)."""
    folder = cache_dir()
    if folder is None:
        return None
    return folder / "outputs" / f"{hashlib.sha256(str(home.absolute()).encode()).hexdigest()[:32]}.json"


def _read_record(home: Path) -> dict[str, dict[str, object]]:
    """Per output file of ``home``'s current generation: its inputs' digest, size, mtime, SHA-256.
    Empty when there is none, or it describes another generation than the current one."""
    path = _record_path(home)
    try:
        current = os.readlink(home / CURRENT)
        record = json.loads(path.read_text(encoding="utf-8")) if path is not None else None
    except (OSError, ValueError):
        return {}
    if not isinstance(record, dict) or record.get("generation") != current:
        return {}
    files = record.get("files")
    return files if isinstance(files, dict) else {}


def _write_record(
    home: Path, generation: str, inputs_of: dict[str, str], previous: dict[str, dict[str, object]]
) -> None:
    """Record the published files as they lie in ``generation`` (a file reused from the previous
    one keeps its digest when its stat did not move: only new files are hashed)."""
    path = _record_path(home)
    if path is None:
        return
    files: dict[str, dict[str, object]] = {}
    for name, inputs in inputs_of.items():
        target = home / generation / name
        try:
            info = target.stat()
            known = previous.get(name)
            if known is not None and (known.get("size"), known.get("mtime_ns")) == (
                info.st_size,
                info.st_mtime_ns,
            ):
                digest = str(known.get("sha256"))
            else:
                digest = file_sha256(target)
        except OSError:
            continue  # not recorded: written again next time
        files[name] = {"inputs": inputs, "size": info.st_size, "mtime_ns": info.st_mtime_ns, "sha256": digest}
    write_atomic(path, json.dumps({"generation": generation, "files": files}, sort_keys=True))


def _reuse(previous: Path, known: dict[str, object], target: Path) -> bool:
    """Link (else copy) the previous generation's file to ``target`` when it is still the file we
    wrote: same size and mtime, or, where the stat moved, the same bytes. A deleted or hand-edited
    output is written again."""
    try:
        info = previous.stat()
        if info.st_size != known.get("size"):
            return False
        if info.st_mtime_ns != known.get("mtime_ns") and file_sha256(previous) != known.get("sha256"):
            return False
        try:
            os.link(previous, target)
        except OSError:  # no hard links on this file system
            shutil.copy2(previous, target)
    except OSError:
        target.unlink(missing_ok=True)
        return False
    return True


def write_outputs(
    space: BlendSpace,
    out_dir: Path,
    formats: Sequence[str],
    fixes: FixState | None = None,
    layer_fixes: dict[str, FixState] | None = None,
    jobs: int = 1,
    maps: EarlyQuality | None = None,
    prepared: SampleDocsAhead | None = None,
) -> tuple[BlendSpaceDocument, list[Path]]:
    """Write every output, or none: a file system refusal (the folder is a file, no permission,
    disk full) is bad input, exit 2, and leaves nothing behind. ``jobs``: processes for the
    foot-skate map's blends; ``maps``: the blend quality maps, already under way (`early_quality`);
    ``prepared``: sample documents made ahead (`to_document.SampleDocsAhead`)."""
    try:
        with _usd_errors_as_os_errors():
            return _write_outputs(
                space, out_dir, formats, fixes or FixState(), layer_fixes or {}, jobs, maps, prepared
            )
    except OSError as error:
        where = error.filename or out_dir
        raise InputError(
            f"cannot write the outputs: {error.strerror or error} ({where})",
            path=space.manifest.path,
            hint="point --out (or output.dir in the manifest) at a folder you can write to",
        ) from None


@contextmanager
def _usd_errors_as_os_errors() -> Iterator[None]:
    """USD reports a failed write (a full disk) as `Tf.ErrorException` with pages of detail: it is
    the same refusal of the file system as an OSError, so it gets the same one-line exit 2."""
    try:
        yield
    except Exception as error:
        if not type(error).__module__.startswith("pxr"):
            raise
        try:
            text = str(error)
        except UnicodeDecodeError:
            text = ""
        if "writ" not in text.lower() and "save" not in text.lower():
            raise  # not a refused write: a bug, exit 3
        detail = re.search(r"'([^'\n]*(?:writ|space|disk)[^'\n]*)'", text, re.IGNORECASE)
        raise OSError(errno.EIO, detail.group(1) if detail else "USD could not write a file") from None


def _write_outputs(
    space: BlendSpace,
    out_dir: Path,
    formats: Sequence[str],
    fixes: FixState,
    layer_fixes: dict[str, FixState],
    jobs: int = 1,
    maps: EarlyQuality | None = None,
    prepared: SampleDocsAhead | None = None,
) -> tuple[BlendSpaceDocument, list[Path]]:
    created = not out_dir.exists()
    out_dir.mkdir(parents=True, exist_ok=True)
    # Generated clips: the main space's under clips/, a beta layer's under clips/<layer>/ (a layer
    # may mirror a clip of the same name as the main space does).
    made = [(space, fixes, "clips")] + [
        (layer.space, layer_fixes[layer.name], f"clips/{_folder_name(layer.name)}")
        for layer in space.layer_spaces
        if isinstance(layer, BetaSpace) and layer.name in layer_fixes
    ]
    # One file per generated clip: names that would share a file name get unique ones.
    stems = {id(sub): unique_stems(s.name for s in sub.samples if s.generated) for sub, _, _ in made}
    for sub, _, folder in made:
        for sample in sub.samples:
            if sample.generated:
                sample.clip.source = out_dir / folder / f"{stems[id(sub)][sample.name]}{source_suffix(sub)}"
    document = to_document(space, out_dir, prepared)
    remove_stale_staging(out_dir)
    staging = Path(tempfile.mkdtemp(prefix=f"{STAGING_PREFIX}{os.getpid()}-", dir=out_dir))
    try:
        # Each document output is written only when what it is made of changed (`_output_inputs`);
        # otherwise the previous generation's file, checked to be the one written, is linked in.
        report = _ReportParts(space)
        writers = _writers(report)
        home = out_dir / GENERATIONS / safe_file_stem(space.name)
        previous = _read_record(home)
        inputs_of: dict[str, str] = {}
        tasks: dict[str, Task] = {}

        def plan(names: Sequence[str], text: str) -> list[str]:
            """The outputs of ``names`` to write (the others are linked in from the previous
            generation), each digested from the document ``text``."""
            digest = hashlib.sha256(text.encode()).hexdigest()
            to_write = []
            for name in names:
                suffix, writer = writers[name]
                file_name = f"{space.name}{suffix}"
                target = staging / file_name
                inputs = _output_inputs(name, file_name, digest, report)
                known = previous.get(file_name)
                if (
                    known is None
                    or known.get("inputs") != inputs
                    or not _reuse(home / CURRENT / file_name, known, target)
                ):
                    tasks[name] = functools.partial(_write_one, name, writer, document, text, target)
                    to_write.append(name)
                inputs_of[file_name] = inputs
            return to_write

        # With --jobs N this process is one writer and N - 1 forked processes are the others (a
        # fork costs a copy of the page tables, so no more): the longest outputs that do not show
        # the blend quality (the PNG first) start now, beside the foot-skate map, and this process
        # writes the rest of them while the map's workers play; after it, up to N - 1 of the rest
        # fork (the longest first) and this process writes what is left, in order.
        # A failure is raised as the serial order of `formats` would have raised it.
        # When the maps are already made (an edit: their child ran beside the rules), the blend
        # quality is known and no writer needs to start early: the writers are shared out between
        # this process and the children by their cost (`_balanced`: at --jobs 2, HTML and USD
        # here, JSON and PNG in one child), instead of three processes on two cores: in traces
        # of served 1,000-clip edits the writers took 0.27-0.31 s instead of 0.34-0.4 s (paired
        # runs of benchmarks/bench_edit_ab.py did not tell the whole edit from noise).
        parallel = jobs > 1 and can_fork()
        slots = jobs - 1 if parallel else 0
        known = parallel and maps is not None and maps.ready()
        blind = sorted((n for n in formats if n in _WITHOUT_BLEND_QUALITY), key=_WRITER_ORDER.index)
        early, beside = (blind[:slots], blind[slots:]) if parallel and not known else ([], [])
        blind_text = document.model_dump_json(indent=2) + "\n" if early or beside else None
        started = plan(early, blind_text) if blind_text is not None else []
        waiting = plan(beside, blind_text) if blind_text is not None else []
        errors: dict[int, BaseException] = {}

        def meanwhile() -> None:
            while waiting:
                name = waiting.pop(0)
                try:
                    tasks[name]()
                except Exception as error:  # weighed against the forked writers' errors below
                    errors[formats.index(name)] = error
                    waiting.clear()

        with Children([tasks[name] for name in started], len(started)) as children:
            # The blend as the engine plays it (error map, drift, foot skate): needs the clips' poses.
            quality = None
            if maps is not None:
                if not maps.ready():
                    meanwhile()  # the outputs beside the maps, while the early child finishes them
                if "html" in formats and not maps.ready():
                    # Still waiting (a cold build: the maps are its longest task): the report's
                    # draft is drawn now, so the HTML written after the maps only adds them.
                    report.draw(document)
                quality = maps.result(document)
            if quality is None:
                quality = blend_quality(
                    space,
                    document,
                    {n: g.clip for n, g in fixes.generated.items()},
                    sync=space.manifest.model.blend.sync,
                    jobs=jobs,
                    meanwhile=meanwhile,
                )
            document.blend_quality = quality
            staged: list[Path] = []  # relative to staging (and to out_dir)
            for sub, state, folder in made:
                in_space = {s.name for s in sub.samples}
                for name in sorted(state.generated):
                    if name in in_space:
                        for path in write_generated_clip(
                            sub, state.generated[name], staging / folder, stems[id(sub)][name]
                        ):
                            staged.append(path.relative_to(staging))
            for relative in staged:
                verify_written(staging / relative)
            late = plan(
                [name for name in formats if name not in early and name not in beside],
                document_text(document, blind_text),
            )
            bundles: list[list[str]] = []  # the late writers each forked process writes, in turn
            here: list[str] = []  # and the ones this process writes after them
            if not parallel:
                run_tasks([tasks[name] for name in late], 1)  # in order, the first failure raised
            elif known:
                here, *bundles = _balanced(late, slots + 1)
            else:
                # The longest late writer (the HTML) forks even while an early child still draws
                # the PNG (a build whose maps took long): this process only has the JSON left, so
                # three processes share two cores for a moment instead of the HTML waiting.
                forked = sorted(late, key=_WRITER_ORDER.index)[: min(slots, len(late) - 1)]
                bundles = [[name] for name in forked]
                here = [name for name in late if name not in forked]
            bundles = [bundle for bundle in bundles if bundle]
            in_turn = [
                functools.partial(_write_in_turn, [(n, tasks[n]) for n in bundle]) for bundle in bundles
            ]
            with Children(in_turn, len(in_turn)) as rest:
                # What waited for the map's workers and has not been written yet (the USD,
                # when the maps were ready at once): here, beside the late children.
                meanwhile()
                for name in here:
                    try:
                        tasks[name]()
                    except Exception as error:  # weighed against the forked writers' errors below
                        errors[formats.index(name)] = error
                        break  # a serial build would not have written the next ones either
                for index, failure in rest.wait().items():
                    errors[formats.index(getattr(failure, _FAILED_WRITER, bundles[index][0]))] = failure
            errors |= {formats.index(started[i]): error for i, error in children.wait().items()}
        if errors:
            raise errors[min(errors)]
        staged += [Path(f"{space.name}{writers[name][0]}") for name in formats]
        generation = publish(staging, out_dir, safe_file_stem(space.name), staged, input_files(space))
        if generation is not None:
            _write_record(home, generation, inputs_of, previous)
        return document, [out_dir / relative for relative in staged]
    except BaseException:
        if created:
            shutil.rmtree(out_dir, ignore_errors=True)
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)


_QUALITY_FIELD = '\n  "blend_quality": null,\n'


def document_text(document: BlendSpaceDocument, blind_text: str | None = None) -> str:
    """``document`` as indented JSON (what the JSON output holds and every output is digested
    from). ``blind_text``: the same document dumped before its blend quality was set; then only
    the blend quality is dumped and put in its place (a 1,000-clip document is not dumped twice).
    Nested objects are indented two more spaces at the top level; a JSON string holds no raw
    newline, so indenting after every newline is exact (tested equal to the whole dump)."""
    quality = document.blend_quality
    if blind_text is None or blind_text.count(_QUALITY_FIELD) != 1:
        return document.model_dump_json(indent=2) + "\n"
    if quality is None:
        return blind_text
    nested = quality.model_dump_json(indent=2).replace("\n", "\n  ")
    return blind_text.replace(_QUALITY_FIELD, f'\n  "blend_quality": {nested},\n')


# Outputs that do not show the document's `blend_quality` (the HTML's engine section and the JSON
# do): with --jobs N they may be written (in forked processes) while the foot-skate map is computed.
# `tests/test_forked_writers.py` checks that their bytes do not depend on it.
_WITHOUT_BLEND_QUALITY = frozenset({"png", "usd"})
# What each writer costs, relative to the others, from the longest to the shortest (on 1,000 clips
# in the build's own process HTML 0.2 s, PNG 0.15 s, USD 0.05 s, JSON 0.03 s; a forked writer
# takes 20-40 % more): in parallel the longest start first, and `_balanced` shares them out.
_WRITER_COST = {"html": 4.0, "png": 4.0, "usd": 1.5, "json": 1.0}
_WRITER_ORDER = tuple(_WRITER_COST)
_FAILED_WRITER = "blendspace_writer"  # set on the error of a writer that failed in `_write_in_turn`


def _balanced(names: Sequence[str], processes: int) -> list[list[str]]:
    """``names`` shared out among ``processes`` (the first is the build's own): each writer, the
    longest first, to the process with the least to do so far; each process's in ``names``' order."""
    loads = [0.0] * processes
    shares: list[list[str]] = [[] for _ in range(processes)]
    for name in sorted(names, key=_WRITER_ORDER.index):
        least = loads.index(min(loads))
        shares[least].append(name)
        loads[least] += _WRITER_COST.get(name, 1.0)
    return [sorted(share, key=list(names).index) for share in shares]


def _write_in_turn(writers: Sequence[tuple[str, Callable[[], None]]]) -> None:
    """Run ``writers`` in order, stopping at the first failure (as a serial build would); its error
    names the writer (`_FAILED_WRITER`), for the parent to weigh it in the order of `formats`."""
    for name, write in writers:
        try:
            write()
        except BaseException as error:
            with contextlib.suppress(Exception):
                setattr(error, _FAILED_WRITER, name)
            raise


def _write_one(
    name: str,
    writer: Callable[[BlendSpaceDocument, Path], None],
    document: BlendSpaceDocument,
    text: str,
    target: Path,
) -> None:
    """Write one output into the staging folder and check it is complete (in a forked writer
    too: a USD refusal becomes the OSError the parent reports, whichever process hit it)."""
    with _usd_errors_as_os_errors():
        if name == "json":
            target.write_text(text, encoding="utf-8")  # the text digested by the caller
        else:
            writer(document, target)
        verify_written(target)


STAGING_PREFIX = ".blendspace-staging-"
_STALE_SECONDS = 3600  # a staging folder whose name carries no pid is stale after an hour


def remove_stale_staging(out_dir: Path) -> None:
    """Remove the staging folders of builds that were killed (their process no longer runs)."""
    for folder in out_dir.glob(f"{STAGING_PREFIX}*"):
        pid_text = folder.name[len(STAGING_PREFIX) :].split("-", 1)[0]
        try:
            if pid_text.isdigit():
                if _running(int(pid_text)):
                    continue
            elif time.time() - folder.lstat().st_mtime < _STALE_SECONDS:
                continue
        except OSError:
            continue
        shutil.rmtree(folder, ignore_errors=True)


def _running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # exists, owned by someone else
        return True
    return True


def _content_hash(staging: Path, files: Sequence[Path]) -> str:
    digest = hashlib.sha256()
    for relative in sorted(files, key=lambda p: p.as_posix()):
        digest.update(relative.as_posix().encode() + b"\0")
        digest.update(hashlib.sha256((staging / relative).read_bytes()).digest())
    return digest.hexdigest()[:16]


def _symlinks_work(folder: Path) -> bool:
    probe = folder / f".blendspace-probe-{os.getpid()}"
    try:
        os.symlink("x", probe)
    except (OSError, NotImplementedError):
        return False
    probe.unlink()
    return True


def publish(
    staging: Path, out_dir: Path, name: str, files: Sequence[Path], sources: Sequence[Path] = ()
) -> str | None:
    """Make the staged ``files`` the output set of blend space ``name`` in one rename (see above).
    ``sources``: the files the build read, never replaced. Returns the generation's folder name
    (None where files are moved into place, no symlinks)."""
    home = out_dir / GENERATIONS / name
    # The sources' identities (a stat each: 1,000 on a library), made once and only when a clip
    # folder's file is in question: most builds have no generated clip to check or tidy.
    read = functools.cache(lambda: _identities(sources))
    _check_targets(out_dir, files, home / CURRENT, read, staging)
    if not _symlinks_work(out_dir):
        for relative in files:
            target = out_dir / relative
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(staging / relative, target)
        return None
    home.mkdir(parents=True, exist_ok=True)
    generation = f"g-{_content_hash(staging, files)}"
    fresh = not (home / generation).is_dir()
    if fresh:
        os.replace(staging, home / generation)
    else:
        _refresh(staging, home / generation, files)
    documents = [relative for relative in files if relative.parent == Path(".")]
    pointer = home / CURRENT
    previous = os.readlink(pointer) if pointer.is_symlink() else None
    switch = home / f".{CURRENT}-{os.getpid()}"
    try:
        # Generated clips are real files (hard links into the generation, else copies): engines
        # import them as assets (Unity does not support symlinked assets) and exporters resolve
        # their paths, which must not lead into a generation folder that the next build deletes.
        # They are placed before the switch, so the new documents never name a clip not there yet.
        clips = [relative for relative in files if relative not in documents]
        for relative in clips:
            _place(home / generation / relative, out_dir / relative)
        if fresh:
            placed = {r.as_posix(): file_sha256(home / generation / r) for r in clips}
            write_atomic(home / generation / PLACED, json.dumps(placed, sort_keys=True))
        if previous != generation:
            switch.unlink(missing_ok=True)
            os.symlink(generation, switch)
            os.replace(switch, pointer)  # the one rename that swaps the whole set
    except BaseException:
        if fresh and previous != generation:  # not switched to: no build will ever use it
            shutil.rmtree(home / generation, ignore_errors=True)
            switch.unlink(missing_ok=True)
        raise
    wanted = {out_dir / relative for relative in files}
    for relative in documents:
        _link(out_dir / relative, home / CURRENT / relative)
    _drop_dangling_links(out_dir, home, wanted)
    if previous is not None and previous != generation:
        _drop_old_clips(out_dir, home / previous, wanted, read)
    for old in home.glob("g-*"):
        if old.name != generation:
            shutil.rmtree(old, ignore_errors=True)
    return generation


def _check_targets(
    out_dir: Path,
    files: Sequence[Path],
    current: Path,
    read: Callable[[], set[tuple[int, int]]],
    staging: Path | None = None,
) -> None:
    """Refuse, before anything moves, an output whose place holds a folder (never deleted: it is
    the user's), whose folder is a file, or (a generated clip) a file this tool did not write: a
    clip of the manifest's (`output.dir: .` puts `clips/` beside the sources) or any other file
    of the user's. The file system would fail half-way through; a clip would be overwritten.
    ``read``: the identities of the files the build read. A clip another blend space published
    into this folder (`build a.yaml b.yaml --out build`, both mirroring a `walk`) is refused too,
    unless this build's (in ``staging``) has the same bytes: its JSON names that clip."""
    others = None
    for relative in files:
        target = out_dir / relative
        if target.is_dir() and not target.is_symlink():
            raise IsADirectoryError(
                errno.EISDIR, "a folder is where an output goes; move or rename it", str(target)
            )
        for folder in list(relative.parents)[:-1]:  # the output folder itself exists by now
            if (out_dir / folder).exists() and not (out_dir / folder).is_dir():
                raise NotADirectoryError(
                    errno.ENOTDIR,
                    "a file is where the outputs' folder goes; move or rename it",
                    str(out_dir / folder),
                )
        if relative.parent == Path(".") or not target.is_file() or target.is_symlink():
            continue
        if _identity(target) in read() or not _generated_here(target, current / relative):
            raise FileExistsError(
                errno.EEXIST,
                "a clip this tool did not generate is where a generated clip goes (it is never "
                "overwritten); rename it, or build to another folder with --out or output.dir",
                str(target),
            )
        if others is None:  # read once, and only when a generated clip's place is taken
            homes = [h for h in (out_dir / GENERATIONS).glob("*") if h != current.parent]
            others = {h / CURRENT: placed_record(h / CURRENT) for h in homes}
        for generation, record in others.items():
            digest = record.get(relative.as_posix())
            if digest is None or not still_placed(target, generation, relative.as_posix(), digest):
                continue
            if staging is None or not filecmp.cmp(staging / relative, target, shallow=False):
                raise FileExistsError(
                    errno.EEXIST,
                    f"blend space {generation.parent.name!r} published a different clip of that name in "
                    "this folder (its JSON names it); give the two spaces their own --out or output.dir",
                    str(target),
                )


def _identity(path: Path | str) -> tuple[int, int] | None:
    """(device, inode) of the file ``path`` names (through links, in any spelling: a symlinked
    folder, another letter case on macOS and Windows); None when there is none."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    return info.st_dev, info.st_ino


def _identities(paths: Sequence[Path]) -> set[tuple[int, int]]:
    return {found for found in map(_identity, paths) if found is not None}


def _generated_here(target: Path, previous: Path) -> bool:
    """Whether ``target`` is a clip a build generated: the previous generation's (the same file or
    the same bytes), or any clip carrying a generated clip's provenance record (an earlier build's,
    an older version's)."""
    try:
        if previous.is_file() and (
            os.path.samefile(target, previous) or filecmp.cmp(target, previous, shallow=False)
        ):
            return True
    except OSError:
        pass
    from blendspace_pipeline.readers.provenance import read_provenance

    return read_provenance(target) is not None


def _drop_old_clips(
    out_dir: Path, previous: Path, wanted: set[Path], read: Callable[[], set[tuple[int, int]]]
) -> None:
    """The previous generation's clips that this set does not have (a fix no longer applied, a
    `--no-fix` build): removed from the clips folder while they are exactly what it placed there
    (the same file, with the bytes it had then), so engines that import every `clips/*` file do not
    import clips the space dropped. Kept: a clip the build read as a source, one another blend
    space published over it, one edited since (in place or saved anew)."""
    # No record of what it placed (an older generation): nothing is known to be ours.
    for relative, digest in sorted(placed_record(previous).items()):
        target = out_dir / relative
        if target in wanted or target.is_symlink() or _identity(target) in read():
            continue
        if still_placed(target, previous, relative, digest):
            with contextlib.suppress(
                OSError
            ):  # gone already: a build never fails over a file it meant to tidy
                target.unlink()


def _refresh(staging: Path, generation: Path, files: Sequence[Path]) -> None:
    """An identical build's generation already exists: a file in it that is not what this build
    wrote (edited by hand through its link, deleted) is replaced, each in one rename."""
    for relative in files:
        new, old = staging / relative, generation / relative
        try:
            if os.path.samefile(new, old) or filecmp.cmp(new, old, shallow=False):
                continue
        except OSError:
            pass
        old.parent.mkdir(parents=True, exist_ok=True)
        os.replace(new, old)


def _place(source: Path, target: Path) -> None:
    """``target`` becomes a real file with ``source``'s content, in one rename."""
    target.parent.mkdir(parents=True, exist_ok=True)
    if target.is_file() and not target.is_symlink() and os.path.samefile(source, target):
        return  # already this generation's file (an identical rebuild)
    temporary = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    temporary.unlink(missing_ok=True)
    try:
        os.link(source, temporary)
    except OSError:  # no hard links on this file system
        shutil.copy2(source, temporary)
    if target.is_dir() and not target.is_symlink():
        shutil.rmtree(target)
    os.replace(temporary, target)
    temporary.unlink(missing_ok=True)  # rename between two links of one file does nothing (POSIX)


def _link(link: Path, target: Path) -> None:
    link.parent.mkdir(parents=True, exist_ok=True)
    relative = os.path.relpath(target, link.parent)
    if link.is_symlink() and os.readlink(link) == relative:
        return
    temporary = link.with_name(f".{link.name}.{os.getpid()}.link")
    temporary.unlink(missing_ok=True)
    os.symlink(relative, temporary)
    os.replace(temporary, link)  # over a previous build's real file too (a folder: `_check_targets`)


def _drop_dangling_links(out_dir: Path, home: Path, wanted: set[Path]) -> None:
    """Links into this blend space's `current` for files the new set does not have."""
    pointer = home / CURRENT
    for folder in [
        out_dir,
        *(p for p in (out_dir / "clips").rglob("*") if p.is_dir() and not p.is_symlink()),
    ]:
        if not folder.is_dir():
            continue
        for link in folder.iterdir():
            if link in wanted or not link.is_symlink():
                continue
            target = Path(os.path.normpath(link.parent / os.readlink(link)))
            if target.is_relative_to(pointer) and not target.exists():
                link.unlink(missing_ok=True)


def build(
    manifest: Path,
    out: Path | None = None,
    *,
    jobs: int = 1,
    progress: Progress | None = None,
    fix: bool = True,
) -> BuildResult:
    early: EarlyQuality | None = None
    # The samples' documents are made while the placeholder simulations run in other processes.
    prepared = SampleDocsAhead(lambda final: output_dir(final, out))

    def start_early(placed: BlendSpace) -> None:
        # Without fixes the placed samples are the final ones: their blend quality maps can be
        # made on another core while this one runs the rules (`early_quality`).
        nonlocal early
        if not fix and jobs > 1 and can_fork():
            try:
                folder = output_dir(placed, out)
            except Exception:  # the writers report a bad output folder, in their turn
                return
            early = EarlyQuality(placed, folder, jobs)

    try:
        # With fixes on, placeholders are checked on the space the fix loop leaves (`apply_fixes`).
        space = analyse(
            manifest,
            jobs=jobs,
            progress=progress,
            converge=not fix,
            on_placed=start_early,
            out=out,
            while_converging=prepared.prepare,
        )
        fixes = FixState()
        layer_fixes: dict[str, FixState] = {}
        if fix:
            space, fixes = apply_fixes(space, jobs=jobs, while_converging=prepared.prepare)
            for layer in space.layer_spaces:  # a beta layer is a blend space: its own `fixes:` apply
                if isinstance(layer, BetaSpace):
                    layer.space, layer_fixes[layer.name] = apply_fixes(layer.space, jobs=jobs)
        out_dir = output_dir(space, out)
        formats = list(dict.fromkeys(space.manifest.model.output.formats))
        document, written = write_outputs(space, out_dir, formats, fixes, layer_fixes, jobs, early, prepared)
    finally:
        if early is not None:
            early.stop()
    return BuildResult(space, document, out_dir, written, fixes, layer_fixes)


def _folder_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)
