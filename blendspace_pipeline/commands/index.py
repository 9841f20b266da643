"""`blendspace index LIBRARY_DIR... --store STORE [--scheduler ADDRESS]`: measure a mocap library
into a shared store (per-clip measurements + a Parquet table) on Dask; see `pipeline.library`."""

from __future__ import annotations

import argparse
import os
import sys
import time

from blendspace_pipeline.commands._arguments import given, given_path
from blendspace_pipeline.cpus import capped_processes
from blendspace_pipeline.errors import EXIT_DIAGNOSTICS, EXIT_OK, UsageError

HELP = "measure a whole mocap library into a shared store of features (on Dask)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "libraries", nargs="+", type=given_path, metavar="LIBRARY_DIR", help="folder(s) of clips"
    )
    parser.add_argument(
        "--store", required=True, type=given, help="store location: a folder or any fsspec URL"
    )
    parser.add_argument(
        "--scheduler",
        type=given,
        metavar="ADDRESS",
        help="a Dask scheduler (default: DASK_SCHEDULER_ADDRESS, else an embedded local cluster)",
    )
    parser.add_argument("--workers", type=int, default=2, help="local cluster workers (default 2)")


def run(args: argparse.Namespace) -> int:
    missing = [str(folder) for folder in args.libraries if not folder.is_dir()]
    if missing:
        raise UsageError(f"not a folder: {', '.join(missing)}", hint="give the library's clip folders")
    if args.workers < 1:
        raise UsageError(f"--workers {args.workers}: need at least 1", hint="e.g. --workers 2")
    if args.scheduler is None and not os.environ.get("DASK_SCHEDULER_ADDRESS"):  # a local cluster
        args.workers = capped_processes(args.workers, "--workers")
    from blendspace_pipeline.pipeline.library import index_library

    start = time.perf_counter()
    rows, errors = index_library(args.libraries, args.store, scheduler=args.scheduler, workers=args.workers)
    seconds = time.perf_counter() - start
    for error in errors:
        sys.stderr.write(f"{error['path']}: {error['error']}\n")
    files = len({row["path"] for row in rows})
    sys.stdout.write(
        f"indexed {len(rows)} animation(s) from {files} file(s) into {args.store} in {seconds:.1f} s"
        + (f"; {len(errors)} file(s) could not be measured (see stderr)" if errors else "")
        + "\n"
    )
    return EXIT_DIAGNOSTICS if errors else EXIT_OK
