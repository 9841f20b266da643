"""A mocap library measured once into a shared, content-addressed store, on Dask.

`index_library` finds every readable clip under the library folders and measures it on a Dask
cluster: an embedded `LocalCluster` by default, or the studio's scheduler (`--scheduler ADDRESS`
or `DASK_SCHEDULER_ADDRESS`). Each worker reads and measures its clips and returns one small
row per animation (features, frames, skeleton signature), never the clip; the parent gathers
the rows into one table. The store is any fsspec location (a folder, a network share, object
storage when its fsspec package is installed):

    STORE/clips/<sha256 of the file's bytes>.json   per-clip measurements (the per-clip cache)
    STORE/index.parquet                             one row per animation, every feature a column

Entries are addressed by content, so a file already in the store (the same bytes, wherever it
lives) is not measured again, and CI, the farm and workstations share the work. `read_index`
loads the table back; `suggest` (commands/suggest.py) looks placeholders up in it. `store_problem`
is the check `build --library` and `suggest --library` share for a store fsspec cannot open.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import os
from collections.abc import Iterable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from blendspace_pipeline import __version__
from blendspace_pipeline.errors import InputError
from blendspace_pipeline.motion.detect import RigSettings
from blendspace_pipeline.motion.measure import Measurement, measure
from blendspace_pipeline.pipeline.cache import MEASUREMENT_REVISION, from_json
from blendspace_pipeline.readers import read_clips, supported_suffixes

INDEX_NAME = "index.parquet"
# The columns every row of an index has (`_row`): without them a Parquet file is someone else's.
INDEX_COLUMNS = frozenset({"path", "digest", "name", "skeleton"})


def store_problem(store: str) -> tuple[str, str] | None:
    """Why fsspec cannot open ``store`` at all, as (what is wrong, how to fix it); None when it can.

    Shared by the commands that take a store (the build's `--library`, `suggest --library`), so
    an unknown protocol or a missing driver reads the same in both. Each says where (the
    manifest, the store) and adds its own way out."""
    if importlib.util.find_spec("fsspec") is None:
        return "needs fsspec, which is not installed", "pip install 'blendspace-pipeline[library]'"
    import fsspec

    try:
        fsspec.core.url_to_fs(store)
    except (ImportError, ValueError, OSError) as error:  # an unknown protocol, a missing driver
        return (
            f"cannot be opened: {error}",
            "give a folder or a URL whose fsspec package is installed (s3fs for s3://, gcsfs for gs://)",
        )
    return None


def store_exists(store: str) -> bool:
    """Whether ``store`` (one fsspec can open: see `store_problem`) is there at all."""
    import fsspec

    fs, root = fsspec.core.url_to_fs(store)
    try:
        return bool(fs.exists(root))
    except OSError:  # unreachable: the reads that follow say so clip by clip, or miss
        return True


def skeleton_signature(joint_names: Iterable[str]) -> str:
    """Clips with the same joints (any order) share a rig: what a suggestion must match."""
    return hashlib.sha256("\n".join(sorted(joint_names)).encode()).hexdigest()[:16]


def layout_signature(joint_names: Sequence[str], joint_parents: Sequence[int]) -> str | None:
    """The same joints under the same parents in the same order: what blending with the set needs
    (`inconsistent-skeleton`). None without the hierarchy (a store indexed before it was measured)."""
    if len(joint_parents) != len(joint_names):
        return None
    text = json.dumps([list(joint_names), [int(p) for p in joint_parents]])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def find_clips(folders: Sequence[Path]) -> list[Path]:
    """Every readable clip file under ``folders`` (recursively), sorted, each once."""
    suffixes = set(supported_suffixes())
    found = {
        path.resolve()
        for folder in folders
        for path in Path(folder).rglob("*")
        if path.is_file() and path.suffix.lower() in suffixes
    }
    return sorted(found)


def _entry_name(digest: str, settings: RigSettings) -> str:
    # The measurement depends on the tool, the measurement code and the rig settings too.
    salt = hashlib.sha256(f"{__version__}|{MEASUREMENT_REVISION}|{settings.cache_key()}".encode()).hexdigest()
    return f"clips/{digest}-{salt[:12]}.json"


def measure_into_store(path: str, store: str, settings: RigSettings) -> list[dict[str, Any]]:
    """Worker task: the rows of one clip file, from the store when its bytes are known there,
    else measured and written to the store. Errors come back as a row with an ``error``."""
    import fsspec

    fs, root = fsspec.core.url_to_fs(store)
    try:
        data = Path(path).read_bytes()
    except OSError as error:
        return [{"path": path, "error": f"cannot read: {error}"}]
    digest = hashlib.sha256(data).hexdigest()
    entry = f"{root.rstrip('/')}/{_entry_name(digest, settings)}"
    measured: list[tuple[str, dict[str, Any]]] | None = None
    if fs.exists(entry):
        try:
            with fs.open(entry, "r") as stream:
                measured = [(item["name"], item["measurement"]) for item in json.load(stream)]
        except (OSError, ValueError, KeyError, TypeError):
            measured = None  # a damaged entry is measured again and rewritten
    if measured is None:
        try:
            measured = [(clip.name, asdict(measure(clip, settings))) for clip in read_clips(Path(path))]
        except Exception as error:  # one bad take must not stop a 100,000-take index
            return [{"path": path, "error": f"{type(error).__name__}: {error}"}]
        fs.makedirs(os.path.dirname(entry), exist_ok=True)
        temporary = f"{entry}.{os.getpid()}.tmp"
        with fs.open(temporary, "w") as stream:
            # The file's stem lets a build that finds these bytes under another name rename them.
            stem = Path(path).stem
            json.dump([{"name": name, "stem": stem, "measurement": m} for name, m in measured], stream)
        fs.mv(temporary, entry)
    return [_row(path, digest, name, m) for name, m in measured]


def lookup(
    store: str, digest: str, path: Path, settings: RigSettings
) -> list[tuple[str, Measurement]] | None:
    """A build's clip file as `blendspace index` measured it, when the store knows its bytes.

    Entries are addressed by content and by the tool, measurement revision and rig settings
    (`_entry_name`), so only a measurement this build would make itself is returned. Clip names
    come from the file's name: an animation named after the library file's stem is renamed after
    this one's. Entries written before the stem was stored, unreadable stores and damaged entries
    give None, and the build measures the file itself.
    """
    import fsspec

    try:
        fs, root = fsspec.core.url_to_fs(store)
        with fs.open(f"{root.rstrip('/')}/{_entry_name(digest, settings)}", "r") as stream:
            items = json.load(stream)
        renamed = []
        for item in items:
            stem, name = item["stem"], item["name"]
            if name == stem or name.startswith(f"{stem}/"):
                name = path.stem + name[len(stem) :]
            renamed.append({"name": name, "measurement": item["measurement"]})
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return from_json(renamed)


def _row(path: str, digest: str, name: str, measurement: dict[str, Any]) -> dict[str, Any]:
    return {
        "path": path,
        "digest": digest,
        "name": name,
        "skeleton": skeleton_signature(measurement.get("joint_names", [])),
        "layout": layout_signature(measurement.get("joint_names", []), measurement.get("joint_parents", [])),
        "frames": int(measurement["frames"]),
        "fps": float(measurement["fps"]),
        "gait_period": measurement.get("gait_period"),
        "in_place": bool(measurement.get("in_place", False)),
        **{f"feature.{key}": float(value) for key, value in measurement["features"].items()},
    }


def connect(scheduler: str | None, workers: int) -> Any:
    """A Dask client: the given scheduler, else DASK_SCHEDULER_ADDRESS, else an embedded local
    cluster of ``workers`` single-threaded processes (measurement holds the GIL)."""
    from distributed import Client, LocalCluster

    address = scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")
    if address:
        return Client(address)  # type: ignore[no-untyped-call]
    cluster = LocalCluster(  # type: ignore[no-untyped-call]
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    )
    return Client(cluster)  # type: ignore[no-untyped-call]


def index_library(
    folders: Sequence[Path],
    store: str,
    *,
    scheduler: str | None = None,
    workers: int = 2,
    settings: RigSettings | None = None,
    batch: int = 64,
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Measure every clip under ``folders`` into ``store``; (rows, errors). Writes the Parquet
    table of all rows (previous rows of files no longer found are dropped)."""
    settings = settings or RigSettings()
    paths = [str(p) for p in find_clips(folders)]
    client = connect(scheduler, workers)
    rows: list[dict[str, Any]] = []
    errors: list[dict[str, Any]] = []
    try:
        # Tasks of `batch` files: per-task overhead stays small next to measuring at 100,000 takes.
        chunks = [paths[i : i + batch] for i in range(0, len(paths), batch)]
        futures = client.map(_measure_batch, chunks, store=store, settings=settings, pure=False)
        for result in client.gather(futures):
            for row in result:
                (errors if "error" in row else rows).append(row)
    finally:
        cluster = getattr(client, "cluster", None)
        client.close()
        if cluster is not None:
            cluster.close()
    write_index(store, rows)
    return rows, errors


def _measure_batch(paths: list[str], store: str, settings: RigSettings) -> list[dict[str, Any]]:
    return [row for path in paths for row in measure_into_store(path, store, settings)]


def write_index(store: str, rows: list[dict[str, Any]]) -> None:
    import fsspec
    import pyarrow as pa
    import pyarrow.parquet as pq

    fs, root = fsspec.core.url_to_fs(store)
    fs.makedirs(root, exist_ok=True)
    columns = sorted({key for row in rows for key in row})
    table = pa.table({column: [row.get(column) for row in rows] for column in columns})
    target = f"{root.rstrip('/')}/{INDEX_NAME}"
    with fs.open(f"{target}.tmp", "wb") as stream:
        pq.write_table(table, stream)
    fs.mv(f"{target}.tmp", target)


def read_index(store: str) -> list[dict[str, Any]]:
    """The rows of the index `blendspace index` wrote to ``store`` (none for an index of an empty
    library).

    Anything else is an InputError (exit 2) naming the store: a store that cannot be opened, is
    not there, is a file, or is a folder without an index (a typo in a CI variable must not read
    as "nothing in the library fits"), and an index that cannot be read."""
    problem = store_problem(store)
    if problem is not None:
        raise InputError(f"the library store {problem[0]}", path=store, hint=problem[1])
    import fsspec
    import pyarrow as pa
    import pyarrow.parquet as pq

    index = f"`blendspace index LIBRARY_DIR --store {store}`"
    fs, root = fsspec.core.url_to_fs(store)
    target = f"{root.rstrip('/')}/{INDEX_NAME}"
    try:
        # The index first: on object storage a "folder" is only a key prefix, so only when the
        # index is missing is the store itself looked at, to say what is there instead.
        if not fs.exists(target):
            if not fs.exists(root):
                raise InputError(
                    "the library store does not exist",
                    path=store,
                    hint=f"check the path, or make one with {index}",
                )
            what = (
                f"no {INDEX_NAME}" if fs.isdir(root) else "a file, not the folder `blendspace index` writes"
            )
            raise InputError(
                f"not a blendspace index ({what})",
                path=store,
                hint=f"check the path, or make one with {index}",
            )
        with fs.open(target, "rb") as stream:
            table = pq.read_table(stream)
    except (OSError, pa.ArrowException) as error:  # unreadable, or not Parquet at all
        raise InputError(
            f"{INDEX_NAME} cannot be read: {error}", path=store, hint=f"make it again with {index}"
        ) from None
    missing = INDEX_COLUMNS - set(table.column_names)
    # An empty library's index has no columns at all, and that is a valid, empty index.
    if table.num_rows and missing:
        raise InputError(
            f"not a blendspace index ({INDEX_NAME} has no {', '.join(sorted(missing))} column)",
            path=store,
            hint=f"check the path, or make one with {index}",
        )
    rows: list[dict[str, Any]] = table.to_pylist()
    return rows
