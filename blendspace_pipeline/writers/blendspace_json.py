"""`N.blendspace.json`: the document (spec.md's layout) with one line per sample, triangle,
finding and placeholder.

`indent=2` spent most of a 10,000-sample file (18 MB) on indentation; one compact line per list
item keeps the file about half that size, still diffs line by line (a changed clip is a changed
line) and reads in any editor. Only whitespace differs from the indented dump: every field, name
and value is pydantic's own serialisation of the model, item by item (in Rust; a json.loads and
dumps round trip of the whole document costs ten times more).
"""

from __future__ import annotations

import json
from pathlib import Path

from pydantic import BaseModel

from blendspace_pipeline.space.document import BlendSpaceDocument


def dumps_document(doc: BlendSpaceDocument) -> str:
    lines = []
    for name in type(doc).model_fields:
        value = getattr(doc, name)
        key = json.dumps(name)
        if isinstance(value, list) and value:
            items = [
                v.model_dump_json() if isinstance(v, BaseModel) else json.dumps(v, separators=(",", ":"))
                for v in value
            ]
            lines.append(f"  {key}: [\n    " + ",\n    ".join(items) + "\n  ]")
        else:
            # The field alone, as pydantic writes it inside the document: '{"name":VALUE}'.
            text = doc.model_dump_json(include={name})
            lines.append(f"  {key}: {text[len(key) + 2 : -1]}")
    return "{\n" + ",\n".join(lines) + "\n}\n"


def write_blendspace_json(doc: BlendSpaceDocument, path: Path) -> None:
    path.write_text(dumps_document(doc), encoding="utf-8")
