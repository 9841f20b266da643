"""The optional compiled kernels (`blendspace_pipeline/_kernels.c`); everything else is in pyproject.toml.

The extension is optional: where no C compiler is found (a Windows machine without Build Tools),
the install goes on without it and the pure-Python code computes the same values, slower.
"""

import sys

from setuptools import Extension, setup

# A fused multiply-add rounds once where numpy rounds twice: the kernels must give numpy's bits.
ARGS = [] if sys.platform == "win32" else ["-O2", "-ffp-contract=off", "-fno-fast-math"]

setup(
    ext_modules=[
        Extension(
            "blendspace_pipeline._kernels",
            ["blendspace_pipeline/_kernels.c"],
            extra_compile_args=ARGS,
            libraries=[] if sys.platform == "win32" else ["m"],  # rint
            optional=True,
        )
    ]
)
