"""`blendspace schema [manifest|blendspace]`: print a JSON Schema generated from the models.

The committed copies in `schemas/` are this output verbatim; `tests/test_schema_sync.py` fails
when they drift from the models and prints the commands that regenerate them.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from pydantic import BaseModel

from blendspace_pipeline.manifest.models import Manifest
from blendspace_pipeline.space.document import BlendSpaceDocument

HELP = "print the JSON Schema of the manifest (default) or of the blend-space JSON"

JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"
# (model, title, file name in schemas/); the $id is a URN because the project has no schema host.
SCHEMAS: dict[str, tuple[type[BaseModel], str, str]] = {
    "manifest": (Manifest, "blendspace-pipeline manifest (schema_version 1)", "manifest.schema.json"),
    "blendspace": (
        BlendSpaceDocument,
        "blendspace-pipeline blend-space JSON (schema_version 1)",
        "blendspace.schema.json",
    ),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "kind", nargs="?", choices=tuple(SCHEMAS), default="manifest", help="which schema (default: manifest)"
    )


def json_schema(kind: str) -> dict[str, Any]:
    model, title, file_name = SCHEMAS[kind]
    schema = model.model_json_schema()
    return {
        "$schema": JSON_SCHEMA_DIALECT,
        "$id": f"urn:blendspace-pipeline:schema:{file_name}",
        **schema,
        "title": title,
    }


def schema_text(kind: str) -> str:
    """The exact text of `schemas/<kind>.schema.json`."""
    return json.dumps(json_schema(kind), indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def run(args: argparse.Namespace) -> int:
    sys.stdout.write(schema_text(args.kind))
    return 0
