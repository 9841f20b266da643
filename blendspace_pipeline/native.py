"""The optional compiled kernels (`_kernels.c`, built by `setup.py` at install), or None.

Callers read ``native.kernels`` when they run, and fall back to their numpy code when it is None
(no C compiler at install time, or ``BLENDSPACE_NO_KERNELS=1``, which benchmarks and bug reports
use to compare the two) or when a kernel declines its input. Both give the same values to the
bit (`tests/test_kernels.py`); only the speed differs.
"""

from __future__ import annotations

import os
from types import ModuleType

NO_KERNELS_VARIABLE = "BLENDSPACE_NO_KERNELS"


def _load() -> ModuleType | None:
    if os.environ.get(NO_KERNELS_VARIABLE, "") not in ("", "0"):
        return None
    try:
        from blendspace_pipeline import _kernels
    except ImportError:  # not built: pure Python
        return None
    return _kernels


kernels = _load()
