"""`python -m blendspace_pipeline` is the same as the `blendspace` console script."""

from blendspace_pipeline.cli import main

raise SystemExit(main())
