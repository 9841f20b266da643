"""The package as installed, for the benchmarks that time `blendspace` in new processes.

`pip install` (not `-e`) compiles every module's bytecode, and an editable checkout writes it on
first import, unless `PYTHONDONTWRITEBYTECODE` is set, as it is on the machines these numbers come
from. There every timed process compiled the modules it imports from source again: 0.15-0.2 s
of a 1,000-clip build's start (importing the pipeline took 0.59-0.65 s, 0.41-0.5 s with
bytecode), and part of every command the build server forwards. `compile_package` writes the
bytecode a user's install has (into `__pycache__/`, which git ignores) before anything is timed.
"""

from __future__ import annotations

import compileall
from pathlib import Path

import blendspace_pipeline


def compile_package() -> None:
    """Compile the package and its built-in rules (written even under PYTHONDONTWRITEBYTECODE)."""
    package = Path(blendspace_pipeline.__file__).resolve().parent
    folders = [package, package.parent / "rules"]
    for folder in folders:
        if folder.is_dir() and not compileall.compile_dir(folder, quiet=1):
            raise SystemExit(f"could not compile {folder}")
