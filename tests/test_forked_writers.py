"""`build --jobs N` writes PNG, HTML, USD and JSON side by side in forked processes: the same bytes
as one after another, and a writer failing in a child fails the build exactly as it does serially
(the same message and exit code, the previous set untouched, no staging folder left)."""

from __future__ import annotations

import errno
import os
import signal
from pathlib import Path

import pytest
from conftest import shared_data
from test_output_faults import _isolated  # noqa: F401 - _isolated is an autouse fixture
from test_output_faults import _project as faults_project

from blendspace_pipeline.cli import main
from blendspace_pipeline.pipeline import forked

NAMES = ("t.blendspace.json", "t.blendspace.usda", "t.report.html", "t.png")

pytestmark = pytest.mark.skipif(not forked.can_fork(), reason="parallel writers need os.fork")


def _project(root: Path, divisions: int = 100) -> Path:
    return faults_project(root, divisions, run=True)


def _outputs(out: Path) -> dict[str, bytes]:
    return {name: (out / name).read_bytes() for name in NAMES}


def _build(manifest: Path, out: Path, capsys: pytest.CaptureFixture[str], jobs: int) -> tuple[int, str]:
    code = main(["build", str(manifest), "--out", str(out), "--jobs", str(jobs)])
    return code, capsys.readouterr().err


def test_parallel_writers_write_the_bytes_of_serial_ones_in_child_processes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path / "p")
    from blendspace_pipeline import report

    real = report.write_png
    where = tmp_path / "png-writer-pids"

    def recording(doc: object, path: Path) -> None:
        with where.open("a", encoding="utf-8") as stream:
            stream.write(f"{os.getpid()}\n")
        real(doc, path)  # type: ignore[arg-type]

    monkeypatch.setattr(report, "write_png", recording)
    assert _build(manifest, tmp_path / "serial", capsys, 1)[0] in (0, 1)
    assert _build(manifest, tmp_path / "parallel", capsys, 2)[0] in (0, 1)
    assert _outputs(tmp_path / "serial") == _outputs(tmp_path / "parallel")
    serial_pid, parallel_pid = (int(line) for line in where.read_text(encoding="utf-8").split())
    assert serial_pid == os.getpid() and parallel_pid != os.getpid()  # --jobs 2 wrote it in a child


def test_parallel_writers_on_real_clips_write_the_serial_bytes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = shared_data("cmu", "131_01.bvh").parent
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        "schema_version: 1\nname: t\nskeleton: {units: 0.0564}\nclips:\n"
        f"  - path: '{data.as_posix()}/131_01.bvh'\n    name: walk_01\n    range: [2.0, 6.0]\n"
        f"  - path: '{data.as_posix()}/131_02.bvh'\n    name: walk_02\n    range: [3.0, 7.0]\n"
        f"  - path: '{data.as_posix()}/131_01.bvh'\n    name: whole_01\n",
        encoding="utf-8",
    )
    serial = _build(manifest, tmp_path / "serial", capsys, 1)
    parallel = _build(manifest, tmp_path / "parallel", capsys, 2)
    assert serial[0] == parallel[0] and serial[0] in (0, 1)
    assert _outputs(tmp_path / "serial") == _outputs(tmp_path / "parallel")


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_full_disk_in_a_writer_exits_2_and_keeps_the_previous_set(
    jobs: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys, jobs)[0] in (0, 1)
    before = _outputs(out)
    from blendspace_pipeline import report

    def full(doc: object, path: Path) -> None:
        path.write_bytes(b"\x89PNG")  # half a file, then the refusal
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(report, "write_png", full)
    _project(tmp_path / "p", 50)
    code, err = _build(manifest, out, capsys, jobs)
    assert code == 2, err
    assert "cannot write the outputs: No space left on device" in err and "hint:" in err
    assert "Traceback" not in err
    assert _outputs(out) == before
    assert not list(out.glob(".blendspace-staging-*"))


def test_a_truncated_png_written_in_a_child_is_caught(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p", 100)
    assert _build(manifest, out, capsys, 2)[0] in (0, 1)
    before = _outputs(out)
    from blendspace_pipeline import report

    real = report.write_png

    def truncated(doc: object, path: Path) -> None:
        real(doc, path)  # type: ignore[arg-type]
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])  # what a full disk did, with no error reported

    monkeypatch.setattr(report, "write_png", truncated)
    _project(tmp_path / "p", 50)
    code, err = _build(manifest, out, capsys, 2)
    assert code == 2, err
    assert "cannot write the outputs" in err and "incomplete" in err
    assert _outputs(out) == before
    assert not list(out.glob(".blendspace-staging-*"))


def test_when_two_writers_fail_the_serial_order_decides_which_error_is_shown(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """HTML comes before PNG in the formats (a serial build stops at the HTML); in parallel the
    PNG starts first and may fail first, yet the message is the HTML's, as serially."""
    manifest = _project(tmp_path / "p")
    from blendspace_pipeline import report

    def html_fails(doc: object, path: Path, inputs: object = (), **_: object) -> None:
        raise OSError(errno.EACCES, os.strerror(errno.EACCES), "the-html")

    def png_fails(doc: object, path: Path) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "the-png")

    monkeypatch.setattr(report, "write_html_report", html_fails)
    monkeypatch.setattr(report, "write_png", png_fails)
    serial = _build(manifest, tmp_path / "serial", capsys, 1)
    parallel = _build(manifest, tmp_path / "parallel", capsys, 2)
    assert serial[0] == parallel[0] == 2
    assert "Permission denied (the-html)" in serial[1]
    assert parallel[1] == serial[1].replace("serial", "parallel")
    assert not (tmp_path / "parallel").exists()  # a folder the build created is removed again


def test_a_bug_in_a_child_writer_is_the_same_internal_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    manifest = _project(tmp_path / "p")
    from blendspace_pipeline import report

    def broken(doc: object, path: Path) -> None:
        raise ValueError("a bug in the PNG writer")

    monkeypatch.setattr(report, "write_png", broken)
    serial = _build(manifest, tmp_path / "serial", capsys, 1)
    parallel = _build(manifest, tmp_path / "parallel", capsys, 2)
    assert serial[0] == parallel[0] == 3
    line = "blendspace: internal error: ValueError: a bug in the PNG writer"
    assert serial[1].startswith(line) and parallel[1].startswith(line)
    log = Path(parallel[1].split("details in ", 1)[1].rstrip(")\n"))
    assert "forked writer process" in log.read_text(encoding="utf-8")  # where it really failed
    assert "broken" in log.read_text(encoding="utf-8")


class _Unpicklable(Exception):
    def __init__(self, text: str, handle: object) -> None:
        super().__init__(text)
        self.handle = handle


def test_an_error_that_cannot_be_pickled_keeps_its_class_name_and_message() -> None:
    def fails() -> None:
        raise _Unpicklable("cannot cross a pipe", lambda: None)

    with pytest.raises(Exception) as caught:
        forked.run_tasks([lambda: None, fails], jobs=2)
    assert type(caught.value).__name__ == "_Unpicklable" and str(caught.value) == "cannot cross a pipe"


def test_a_child_killed_by_a_signal_is_an_error_and_the_others_finish(tmp_path: Path) -> None:
    done = tmp_path / "done"

    def killed() -> None:
        os.kill(os.getpid(), signal.SIGKILL)

    with pytest.raises(RuntimeError, match="killed by signal 9"):
        forked.run_tasks([killed, lambda: done.write_text("x", encoding="utf-8")], jobs=2)
    assert done.read_text(encoding="utf-8") == "x"


def test_jobs_1_runs_in_this_process_in_order_and_stops_at_the_first_failure() -> None:
    ran: list[tuple[str, int]] = []

    def fails() -> None:
        ran.append(("b", os.getpid()))
        raise KeyError("b")

    with pytest.raises(KeyError):
        forked.run_tasks([lambda: ran.append(("a", os.getpid())), fails, lambda: ran.append(("c", 0))], 1)
    assert ran == [("a", os.getpid()), ("b", os.getpid())]


def test_more_tasks_than_jobs_all_run_and_start_in_the_given_order(tmp_path: Path) -> None:
    log = tmp_path / "log"

    def task(name: str) -> forked.Task:
        def run() -> None:
            with log.open("a", encoding="utf-8") as stream:
                stream.write(f"{name} {os.getpid()}\n")

        return run

    forked.run_tasks([task(str(i)) for i in range(5)], jobs=2, start_order=[4, 3, 2, 1, 0])
    lines = [line.split() for line in log.read_text(encoding="utf-8").splitlines()]
    assert sorted(name for name, _ in lines) == ["0", "1", "2", "3", "4"]
    assert len({pid for _, pid in lines}) == 5 and str(os.getpid()) not in {pid for _, pid in lines}


def test_the_outputs_written_beside_the_foot_skate_map_do_not_show_it(tmp_path: Path) -> None:
    """PNG and USD start before the blend quality is known (`outputs._WITHOUT_BLEND_QUALITY`):
    their bytes must be the same without it."""
    from blendspace_pipeline.pipeline import outputs
    from blendspace_pipeline.pipeline.outputs import build
    from blendspace_pipeline.report import write_png
    from blendspace_pipeline.writers.usd_blendspace import usda_text

    assert {"png", "usd"} == outputs._WITHOUT_BLEND_QUALITY
    document = build(_project(tmp_path / "p"), tmp_path / "out").document
    assert document.blend_quality is not None
    blind = document.model_copy(update={"blend_quality": None})
    assert usda_text(document) == usda_text(blind)
    write_png(document, tmp_path / "with.png")
    write_png(blind, tmp_path / "without.png")
    assert (tmp_path / "with.png").read_bytes() == (tmp_path / "without.png").read_bytes()


def test_a_failing_foot_skate_map_stops_the_writers_already_started(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The PNG and USD children run while the map is computed; the map's error is the build's
    (as serially, where no writer had started), and no child writes on into a removed folder."""
    out = tmp_path / "out"
    manifest = _project(tmp_path / "p")
    assert _build(manifest, out, capsys, 2)[0] in (0, 1)
    before = _outputs(out)
    from blendspace_pipeline import report
    from blendspace_pipeline.pipeline import outputs

    real = report.write_png
    flag = tmp_path / "png-finished"

    def slow(doc: object, path: Path) -> None:
        import time

        time.sleep(3)
        real(doc, path)  # type: ignore[arg-type]
        flag.write_text("x", encoding="utf-8")

    def failing(*args: object, **kwargs: object) -> None:
        raise OSError(errno.EIO, os.strerror(errno.EIO), "the-map")

    monkeypatch.setattr(report, "write_png", slow)
    monkeypatch.setattr(outputs, "blend_quality", failing)
    _project(tmp_path / "p", 50)
    serial = _build(manifest, tmp_path / "serial-out", capsys, 1)
    code, err = _build(manifest, out, capsys, 2)
    assert (code, err.replace(str(out), "OUT")) == (
        serial[0],
        serial[1].replace(str(tmp_path / "serial-out"), "OUT"),
    )
    assert code == 2 and "Input/output error (the-map)" in err
    assert _outputs(out) == before and not list(out.glob(".blendspace-staging-*"))
    import time

    time.sleep(3.5)
    assert not flag.exists()  # the PNG child was stopped, not left writing


def test_the_document_text_with_the_blend_quality_put_in_is_the_whole_dump(tmp_path: Path) -> None:
    from blendspace_pipeline.pipeline.outputs import build, document_text

    document = build(_project(tmp_path / "p"), tmp_path / "out", fix=False).document
    assert document.blend_quality is not None
    whole = document.model_dump_json(indent=2) + "\n"
    blind = document.model_copy(update={"blend_quality": None})
    blind_text = blind.model_dump_json(indent=2) + "\n"
    assert document_text(document, blind_text) == whole
    assert document_text(blind, blind_text) == blind_text
    assert document_text(document) == whole
    assert document_text(document, "not a document") == whole  # no field to fill: dumped whole


def test_without_fork_jobs_2_writes_everything_here_in_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from blendspace_pipeline import report
    from blendspace_pipeline.pipeline import outputs

    order: list[tuple[str, int]] = []
    real_png, real_html = report.write_png, report.write_html_report

    def png(doc: object, path: Path) -> None:
        order.append(("png", os.getpid()))
        real_png(doc, path)  # type: ignore[arg-type]

    def html(doc: object, path: Path, inputs: object = (), **options: object) -> None:
        order.append(("html", os.getpid()))
        real_html(doc, path, inputs, **options)  # type: ignore[arg-type]

    monkeypatch.setattr(report, "write_png", png)
    monkeypatch.setattr(report, "write_html_report", html)
    monkeypatch.setattr(outputs, "can_fork", lambda: False)  # as on Windows
    manifest = _project(tmp_path / "p")
    assert _build(manifest, tmp_path / "no-fork", capsys, 2)[0] in (0, 1)
    assert order == [("html", os.getpid()), ("png", os.getpid())]  # the formats' order, here
    monkeypatch.setattr(report, "write_png", real_png)
    monkeypatch.setattr(report, "write_html_report", real_html)
    assert _build(manifest, tmp_path / "serial", capsys, 1)[0] in (0, 1)
    assert _outputs(tmp_path / "no-fork") == _outputs(tmp_path / "serial")


@pytest.mark.parametrize("maps_ready", [True, False])
def test_an_edits_writers_are_shared_out_and_write_the_serial_bytes(
    maps_ready: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """When the early maps are ready by the time the writers start (an edit), the writers are
    shared out between this process and the children (`outputs._balanced`): the HTML here, the
    PNG in a child; otherwise the PNG starts early in a child. The bytes are the serial ones."""
    from blendspace_pipeline import report
    from blendspace_pipeline.pipeline.early_quality import EarlyQuality

    manifest = _project(tmp_path / "p")
    monkeypatch.setattr(EarlyQuality, "ready", lambda self: maps_ready)
    where = tmp_path / "writer-pids"
    for name in ("write_png", "write_html_report"):
        real = getattr(report, name)

        def recording(
            doc: object, path: Path, *args: object, _real: object = real, _name: str = name, **kw: object
        ) -> None:
            with where.open("a", encoding="utf-8") as stream:
                stream.write(f"{_name} {os.getpid()}\n")
            _real(doc, path, *args, **kw)  # type: ignore[operator]

        monkeypatch.setattr(report, name, recording)
    built = [
        main(["build", str(manifest), "--no-fix", "--out", str(tmp_path / o), "--jobs", j])
        for o, j in (("serial", "1"), ("parallel", "2"))
    ]
    capsys.readouterr()
    assert built[0] == built[1] and built[0] in (0, 1)
    assert _outputs(tmp_path / "serial") == _outputs(tmp_path / "parallel")
    pids = [line.split() for line in where.read_text(encoding="utf-8").splitlines()]
    parallel = {name: int(pid) for name, pid in pids[2:]}
    assert parallel["write_png"] != os.getpid()
    assert (parallel["write_html_report"] == os.getpid()) is maps_ready


def test_writers_shared_out_fail_in_the_serial_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The USD (written here) and the PNG (in a child, after the JSON) both fail: the USD's error
    is shown, as serially; the PNG alone failing in its child is shown with its own message."""
    from blendspace_pipeline import report
    from blendspace_pipeline.pipeline import outputs
    from blendspace_pipeline.pipeline.early_quality import EarlyQuality

    assert outputs._balanced(["json", "usd", "html", "png"], 2) == [["usd", "html"], ["json", "png"]]
    assert outputs._balanced(["json", "usd", "html", "png"], 4) == [["html"], ["png"], ["usd"], ["json"]]
    assert outputs._balanced(["json"], 2) == [["json"], []]
    manifest = _project(tmp_path / "p")
    monkeypatch.setattr(EarlyQuality, "ready", lambda self: True)

    def png_fails(doc: object, path: Path) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "the-png")

    monkeypatch.setattr(report, "write_png", png_fails)
    shown = []
    for usd_fails in (False, True):
        if usd_fails:
            from blendspace_pipeline.writers import usd_blendspace

            def usd_refused(doc: object, path: Path) -> None:
                raise OSError(errno.EACCES, os.strerror(errno.EACCES), "the-usd")

            monkeypatch.setattr(usd_blendspace, "write_usd_blendspace", usd_refused)
        for jobs in ("1", "2"):
            out = tmp_path / f"{usd_fails}-{jobs}"
            code = main(["build", str(manifest), "--no-fix", "--out", str(out), "--jobs", jobs])
            shown.append((code, capsys.readouterr().err.replace(str(out), "OUT")))
            assert not out.exists()
    assert shown[0] == shown[1] and shown[0][0] == 2 and "the-png" in shown[0][1]
    assert shown[2] == shown[3] and shown[2][0] == 2 and "Permission denied (the-usd)" in shown[2][1]


def test_a_build_makes_its_sample_documents_beside_the_simulations_and_writes_the_serial_bytes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from blendspace_pipeline.pipeline import placeholders, to_document

    monkeypatch.setattr(placeholders, "PARALLEL_FROM", 0)  # the 13-clip sample: simulate side by side
    prepared: list[int] = []
    real = to_document.SampleDocsAhead.prepare

    def counted(self: to_document.SampleDocsAhead, space: object) -> None:
        prepared.append(os.getpid())
        real(self, space)  # type: ignore[arg-type]

    monkeypatch.setattr(to_document.SampleDocsAhead, "prepare", counted)
    sample = Path(__file__).resolve().parents[1] / "sample_project" / "manifest.yaml"
    for out, jobs, fixes in (("s", "1", False), ("p", "2", False), ("sf", "1", True), ("pf", "2", True)):
        args = ["build", str(sample), "--out", str(tmp_path / out), "--jobs", jobs]
        assert main(args if fixes else [*args, "--no-fix"]) in (0, 1)
    capsys.readouterr()
    assert prepared == [os.getpid(), os.getpid()]  # once per --jobs 2 build, here
    names = sorted(p.name for p in (tmp_path / "s").iterdir() if p.is_file())
    assert names and all(
        (tmp_path / "s" / n).read_bytes() == (tmp_path / "p" / n).read_bytes() for n in names
    )
    names = sorted(p.name for p in (tmp_path / "sf").iterdir() if p.is_file())
    assert all((tmp_path / "sf" / n).read_bytes() == (tmp_path / "pf" / n).read_bytes() for n in names)
