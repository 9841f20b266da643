"""Read a manifest YAML file into validated models, keeping where every key was written.

ruamel.yaml's round-trip loader records the line and column of each key and list item; the loader
keeps that tree so any later stage (path resolution, rule findings) can point at the exact line
with `LoadedManifest.locate`. Every way a manifest can be wrong becomes a `ManifestError` with a
position and a hint; validation problems are all reported at once (`ManifestProblemsError`).
"""

from __future__ import annotations

import difflib
import math
import os
import re
import stat
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, NoReturn, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo
from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import MarkedYAMLError, YAMLError

from blendspace_pipeline.errors import ManifestError
from blendspace_pipeline.manifest.models import LAYER_KINDS, Manifest

# Far more than any real manifest (a few hundred values), far less than an alias bomb expands to.
MAX_NODES = 100_000
MAX_DEPTH = 64
# A key path into the manifest: mapping keys and list indices, e.g. ("clips", 2, "range").
KeyPath = tuple[str | int, ...]
MINIMAL_MANIFEST = "schema_version: 1\nname: locomotion\nclips:\n  - path: clips/*.bvh"


@dataclass
class LoadedManifest:
    """A validated manifest with the YAML tree that remembers where each key was written."""

    path: Path
    model: Manifest
    directory: Path
    tree: CommentedMap = field(repr=False, compare=False)

    def locate(self, key_path: KeyPath) -> tuple[int, int]:
        """1-based (line, column) of a key or list item; the nearest existing parent when absent."""
        return locate_in(self.tree, key_path)

    def error_at(self, key_path: KeyPath, message: str, hint: str) -> ManifestError:
        """A `ManifestError` (exit 2) pointing at ``key_path``'s line in this manifest."""
        line, column = self.locate(key_path)
        return ManifestError(message, path=self.path, line=line, column=column, hint=hint)


def locate_in(tree: Any, key_path: KeyPath) -> tuple[int, int]:
    node = tree
    line, column = _start_of(tree)
    for key in key_path:
        try:
            if isinstance(node, CommentedMap):
                row, col = node.lc.key(key)
            elif isinstance(node, CommentedSeq) and isinstance(key, int) and 0 <= key < len(node):
                row, col = node.lc.item(key)
            else:
                break
            node = node[key]
        except (KeyError, TypeError, IndexError):
            # Keys pulled in by a `<<:` merge have no position of their own.
            break
        line, column = row + 1, col + 1
    return line, column


def _start_of(tree: Any) -> tuple[int, int]:
    if isinstance(tree, CommentedMap | CommentedSeq) and tree.lc.line is not None:
        return tree.lc.line + 1, tree.lc.col + 1
    return 1, 1


def load_manifest(path: Path) -> LoadedManifest:
    """Read, parse and validate ``path``; raises `ManifestError` (exit 2) on any problem."""
    path = Path(path)
    text = _read_text(path)
    tree = _parse(text, path)
    raw = _to_plain(tree, path)
    _check_surrogates(raw, tree, path)
    _check_schema_version(raw, tree, path)
    try:
        model = Manifest.model_validate(raw)
    except ValidationError as error:
        problems = translate(error, raw, lambda key_path: locate_in(tree, key_path))
        raise ManifestProblemsError.from_problems(path, problems) from None
    _check_limits(model, tree, path)
    _check_hand_positions(model, tree, path)
    return LoadedManifest(path=path, model=model, directory=Path(os.path.abspath(path)).parent, tree=tree)


_SURROGATE = re.compile("[\ud800-\udfff]")


def _check_surrogates(raw: Any, tree: CommentedMap, path: Path, key_path: KeyPath = ()) -> None:
    """A YAML escape such as "\\ud800" makes a lone UTF-16 surrogate: no file name or output can
    hold one (found by the fuzzer as a UnicodeEncodeError deep in the build)."""
    items = raw.items() if isinstance(raw, dict) else enumerate(raw) if isinstance(raw, list) else ()
    for key, value in items:
        where: KeyPath = (*key_path, key)
        if (isinstance(key, str) and _SURROGATE.search(key)) or (
            isinstance(value, str) and _SURROGATE.search(value)
        ):
            line, column = locate_in(tree, where)
            raise ManifestError(
                f"{dotted(where)} holds an unpaired UTF-16 surrogate escape (\\ud800-\\udfff)",
                path=path,
                line=line,
                column=column,
                hint="write the character itself, or a \\U escape of a real code point",
            )
        _check_surrogates(value, tree, path, where)


# Hard limits on numbers the schema accepts but no blend space can use: a grid of 10**1000 cells
# overflows a float, an axis of +-1e308 has no finite width, a unit of 9e18 m is not a rig.
MAX_DIVISIONS = 100_000
MAX_AXIS_VALUE = 1e6
MIN_AXIS_SPAN = 1e-6
UNIT_RANGE = (1e-6, 1e6)  # metres per file unit
MAX_CLIP_ENTRIES = 10_000
MAX_SECONDS = 1e6  # a `range:` end; any real take is far shorter


def _check_limits(model: Manifest, tree: CommentedMap, path: Path) -> None:
    def fail(key_path: KeyPath, message: str, hint: str) -> NoReturn:
        line, column = locate_in(tree, key_path)
        raise ManifestError(message, path=path, line=line, column=column, hint=hint)

    for name in ("x", "y"):
        axis = getattr(model.axes, name)
        where: KeyPath = ("axes", name)
        if axis.divisions > MAX_DIVISIONS:
            fail(
                (*where, "divisions"),
                f"axes.{name}.divisions: {_number(axis.divisions)} is more than the limit of {MAX_DIVISIONS:,}",
                "a few hundred grid intervals are plenty; e.g. divisions: 100",
            )
        for end in ("min", "max"):
            value = getattr(axis, end)
            if not math.isfinite(value) or abs(value) > MAX_AXIS_VALUE:
                fail(
                    (*where, end),
                    f"axes.{name}.{end}: {value:g} is out of range (|value| <= {MAX_AXIS_VALUE:g})",
                    "give the axis range in the feature's unit, e.g. min: -180, max: 180",
                )
        if axis.max - axis.min < MIN_AXIS_SPAN:
            fail(
                (*where, "max"),
                f"axes.{name}: the range {axis.min:g}..{axis.max:g} is too narrow",
                "widen the range so clips can differ along it",
            )
    for index, entry in enumerate(model.clips):
        trim = entry.range if isinstance(entry.range, tuple | list) else None
        if trim is not None and not all(math.isfinite(v) and abs(v) <= MAX_SECONDS for v in trim):
            fail(
                ("clips", index, "range"),
                f"clips[{index}].range: {trim[0]:g}..{trim[1]:g} s is out of range (0..{MAX_SECONDS:g} s)",
                "give the trim in seconds of the clip, e.g. range: [0.5, 2.5]",
            )
    settings: list[tuple[KeyPath, object]] = [(("skeleton",), model.skeleton)]
    for index, entry in enumerate(model.clips):
        own = getattr(entry, "skeleton", None)
        if own is not None:
            settings.append((("clips", index, "skeleton"), own))
    for key_path, skeleton in settings:
        units = getattr(skeleton, "units", "auto")
        if isinstance(units, int | float) and not UNIT_RANGE[0] <= units <= UNIT_RANGE[1]:
            fail(
                (*key_path, "units"),
                f"{dotted(key_path)}.units: {_number(units)} metres per unit is out of range "
                f"({UNIT_RANGE[0]:g}..{UNIT_RANGE[1]:g})",
                "use a named unit (m, cm, mm, in) or metres per file unit, e.g. units: 0.01 for cm",
            )
    if len(model.clips) > MAX_CLIP_ENTRIES:
        fail(
            ("clips",),
            f"the manifest lists {len(model.clips):,} clip entries, more than the limit of {MAX_CLIP_ENTRIES:,}",
            "use globs (clips/*.bvh) or split the blend space",
        )


def _check_hand_positions(model: Manifest, tree: CommentedMap, path: Path) -> None:
    """A hand placement (`clips[].position`) must lie on the axes: an engine could not hold it."""
    axes = (model.axes.x, model.axes.y)
    for index, entry in enumerate(model.clips):
        if entry.position is None:
            continue
        for value, axis, name in zip(entry.position, axes, "xy", strict=True):
            if not axis.min <= value <= axis.max:
                line, column = locate_in(tree, ("clips", index, "position"))
                raise ManifestError(
                    f"clips[{index}].position: {value:g} is outside the {name} axis "
                    f"({axis.feature}) range [{axis.min:g}, {axis.max:g}]",
                    path=path,
                    line=line,
                    column=column,
                    hint="give the position in axis units and order (x, y), inside the axis ranges",
                )


MAX_MANIFEST_BYTES = 10 * 1024 * 1024  # a manifest is a few kB; a huge one is an accident or hostile


def _read_manifest_bytes(path: Path) -> bytes:
    """The manifest's bytes: a regular file only (a FIFO would hang, /dev/zero fill the memory)."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    handle = os.open(path, flags)
    try:
        info = os.fstat(handle)
        if stat.S_ISDIR(info.st_mode):
            raise IsADirectoryError(21, "Is a directory", str(path))
        if not stat.S_ISREG(info.st_mode):
            raise ManifestError(
                "the manifest is not a regular file (a device, FIFO or socket)",
                path=path,
                hint="pass the manifest's YAML file",
            )
        if info.st_size > MAX_MANIFEST_BYTES:
            raise ManifestError(
                f"the manifest is {info.st_size:,} bytes, more than the limit of {MAX_MANIFEST_BYTES:,}",
                path=path,
                hint="a manifest lists clips and settings; use globs for long clip lists",
            )
        with os.fdopen(handle, "rb") as stream:
            handle = -1
            return stream.read(MAX_MANIFEST_BYTES + 1)
    finally:
        if handle >= 0:
            os.close(handle)


def _read_text(path: Path) -> str:
    try:
        data = _read_manifest_bytes(path)
    except FileNotFoundError:
        raise ManifestError("manifest not found", path=path, hint=_nearby_hint(path)) from None
    except IsADirectoryError:
        raise ManifestError(
            "this is a folder, not a manifest file",
            path=path,
            hint="pass the manifest's YAML file, e.g. blendspace build project/locomotion.yaml",
        ) from None
    except OSError as error:
        raise ManifestError(
            f"cannot read the manifest: {error.strerror or error}",
            path=path,
            hint="check the file's permissions",
        ) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data.count(b"\n", 0, error.start) + 1
        column = error.start - (data.rfind(b"\n", 0, error.start) + 1) + 1
        raise ManifestError(
            f"the manifest is not UTF-8 text (byte 0x{data[error.start]:02x})",
            path=path,
            line=line,
            column=column,
            hint="save the file as UTF-8",
        ) from None


def _nearby_hint(path: Path) -> str:
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        return f"the folder {folder} does not exist"
    names = sorted(p.name for p in folder.iterdir() if p.suffix.lower() in (".yaml", ".yml"))
    close = difflib.get_close_matches(path.name, names, n=3)
    if close:
        return "did you mean " + " or ".join(repr(str(folder / name)) for name in close) + "?"
    return f"YAML files in {folder}: {', '.join(names[:10])}" if names else f"no .yaml file in {folder}"


def _parse(text: str, path: Path) -> CommentedMap:
    yaml = YAML(typ="rt")
    try:
        tree = yaml.load(text)
    except MarkedYAMLError as error:
        raise _yaml_error(error, path) from None
    except RecursionError:
        raise ManifestError(
            "the manifest nests too deeply to read", path=path, hint="flatten the nested brackets"
        ) from None
    except YAMLError as error:  # reader errors (control characters) carry no mark, but a position
        position = getattr(error, "position", None)
        character = getattr(error, "character", None)
        line = column = None
        if isinstance(position, int) and 0 <= position <= len(text):
            line = text.count("\n", 0, position) + 1
            column = position - (text.rfind("\n", 0, position) + 1) + 1
        if isinstance(character, str) and len(character) == 1:
            character = ord(character)
        what = f" U+{character:04X}" if isinstance(character, int) else ""
        raise ManifestError(
            f"invalid YAML: the control character{what} is not allowed in YAML",
            path=path,
            line=line,
            column=column,
            hint="remove it; write a backslash as '\\\\' in double quotes or use single quotes",
        ) from None
    if tree is None:
        raise ManifestError(
            "manifest is empty",
            path=path,
            line=1,
            column=1,
            hint="a minimal manifest is:\n" + MINIMAL_MANIFEST,
        )
    if not isinstance(tree, CommentedMap):
        raise ManifestError(
            f"the manifest's top level is {_kind(tree)}, not a mapping of keys",
            path=path,
            line=1,
            column=1,
            hint="start with `schema_version: 1`, then name:, clips:, …",
        )
    return tree


_DUPLICATE = re.compile(r'found duplicate key "(?P<key>.*?)"')


def _yaml_error(error: MarkedYAMLError, path: Path) -> ManifestError:
    mark = error.problem_mark or error.context_mark
    line, column = (mark.line + 1, mark.column + 1) if mark is not None else (None, None)
    problem = str(error.problem or error.context or "invalid YAML")
    duplicate = _DUPLICATE.search(problem)
    if duplicate:
        first = error.context_mark
        where = f" (the mapping starts on line {first.line + 1})" if first is not None else ""
        return ManifestError(
            f"duplicate key {duplicate['key']!r}{where}",
            path=path,
            line=line,
            column=column,
            hint="each key may appear once per mapping; delete or merge one of them",
        )
    started = ""
    if error.context and error.problem and error.context_mark is not None:
        start = error.context_mark
        started = f" ({error.context} that starts at line {start.line + 1}, column {start.column + 1})"
    return ManifestError(
        f"invalid YAML: {problem}{started}",
        path=path,
        line=line,
        column=column,
        hint="check the indentation, colons and brackets here (quote values holding ': ' or ' #')",
    )


def _kind(value: object) -> str:
    if isinstance(value, list):
        return "a list"
    return "a string" if isinstance(value, str) else f"a {type(value).__name__}"


@dataclass
class _Converter:
    """Turns the ruamel tree into plain dicts/lists, counting values so aliases cannot explode.

    ruamel builds an alias as a shared reference, so a "billion laughs" document loads in
    milliseconds; it is the expansion into plain data (and pydantic after it) that would not end.
    """

    path: Path
    tree: CommentedMap
    count: int = 0

    def convert(self, node: Any, key_path: KeyPath) -> Any:
        self.count += 1
        if self.count > MAX_NODES:
            self._fail(
                f"the manifest expands to more than {MAX_NODES} values",
                key_path[:1],
                "a YAML alias (*name) repeats a large anchored block many times (an 'alias bomb'); "
                "write the values out",
            )
        if isinstance(node, dict):
            self._check_depth(key_path)
            return {self.convert(k, key_path): self.convert(v, (*key_path, k)) for k, v in node.items()}
        if isinstance(node, list):
            self._check_depth(key_path)
            return [self.convert(item, (*key_path, index)) for index, item in enumerate(node)]
        if isinstance(node, bool):
            return bool(node)
        # ruamel's ScalarFloat/ScalarInt/ScalarString subclasses become the plain types pydantic expects.
        for plain in (int, float, str):
            if isinstance(node, plain):
                return plain(node)
        return node

    def _check_depth(self, key_path: KeyPath) -> None:
        if len(key_path) > MAX_DEPTH:
            self._fail(
                f"the manifest nests deeper than {MAX_DEPTH} levels", key_path, "flatten the structure"
            )

    def _fail(self, message: str, key_path: KeyPath, hint: str) -> NoReturn:
        line, column = locate_in(self.tree, key_path)
        raise ManifestError(message, path=self.path, line=line, column=column, hint=hint)


def _to_plain(tree: CommentedMap, path: Path) -> dict[Any, Any]:
    plain: dict[Any, Any] = _Converter(path, tree).convert(tree, ())
    return plain


def _check_schema_version(raw: dict[Any, Any], tree: CommentedMap, path: Path) -> None:
    """Checked before anything else: other keys mean nothing until the version is known."""
    if "schema_version" not in raw:
        line, column = _start_of(tree)
        raise ManifestError(
            "missing `schema_version`",
            path=path,
            line=line,
            column=column,
            hint="add `schema_version: 1` as the first line of the manifest",
        )
    version = raw["schema_version"]
    if type(version) is not int or version != 1:
        line, column = locate_in(tree, ("schema_version",))
        if isinstance(version, str) and version.strip() == "1":
            raise ManifestError(
                "schema_version is the text '1', not the number 1",
                path=path,
                line=line,
                column=column,
                hint="write `schema_version: 1` without quotes",
            )
        raise ManifestError(
            f"unsupported schema_version {version if type(version) in (int, float) else describe(version)}: "
            "this blendspace-pipeline reads version 1",
            path=path,
            line=line,
            column=column,
            hint="write `schema_version: 1` (a manifest made for a newer version needs a newer tool)",
        )


# --- validation problems -------------------------------------------------------------------------
# pydantic reports a location such as ("layers", 2, "style", "clips", 1, "ClipEntry", "rnage"): the
# data keys mixed with the names of union members it tried. Walking it against the data separates
# the two, which gives the key path to show (layers[2].clips[1].rnage) and to locate in the file.

Locator = Callable[[KeyPath], tuple[int, int]]

_EXPECTED = {
    "string_type": "text",
    "float_type": "a number",
    "float_parsing": "a number",
    "finite_number": "a finite number",
    "int_type": "a whole number",
    "int_parsing": "a whole number",
    "int_from_float": "a whole number",
    "bool_type": "true or false",
    "bool_parsing": "true or false",
    "list_type": "a list",
    "tuple_type": "a list",
    "dict_type": "a mapping",
    "model_type": "a mapping",
    "model_attributes_type": "a mapping",
}
_BOUNDS = {
    "greater_than": ("gt", ">"),
    "greater_than_equal": ("ge", ">="),
    "less_than": ("lt", "<"),
    "less_than_equal": ("le", "<="),
}
_QUOTED = re.compile(r"'((?:[^'\\]|\\.)*)'")


@dataclass(frozen=True)
class Problem:
    """One thing wrong in the manifest, at its own line and column."""

    key_path: KeyPath
    message: str
    hint: str | None
    line: int
    column: int

    def text(self) -> str:
        where = dotted(self.key_path)
        return f"{where}: {self.message}" if where else self.message


def dotted(key_path: KeyPath) -> str:
    """("clips", 2, "range") -> "clips[2].range"."""
    text = ""
    for key in key_path:
        text += f"[{key}]" if isinstance(key, int) else ("." if text else "") + str(key)
    return text


@dataclass
class ManifestProblemsError(ManifestError):
    """Every validation problem at once; the fields describe the first (in file order)."""

    problems: tuple[Problem, ...] = ()

    @classmethod
    def from_problems(cls, path: Path, problems: list[Problem]) -> ManifestProblemsError:
        first = problems[0]
        others = [f"{path}:{p.line}:{p.column}: {p.text()}" for p in problems[1:]]
        return cls(
            "\n".join([first.text(), *others]),
            path=path,
            line=first.line,
            column=first.column,
            hint=first.hint,
            problems=tuple(problems),
        )

    def render(self) -> str:
        return "\n".join(
            ManifestError(p.text(), path=self.path, line=p.line, column=p.column, hint=p.hint).render()
            for p in self.problems
        )


@dataclass
class _Entry:
    """One pydantic error with its key path in the data."""

    error: Any
    key_path: KeyPath
    via_union: bool = False  # one union member rejected the value as a whole
    about_key: bool = False  # the mapping key itself is invalid (pydantic's "[key]")
    short_list: bool = False  # a fixed-size pair such as range: [start, end] lacks a value

    @property
    def type(self) -> str:
        return str(self.error["type"])

    @property
    def ctx(self) -> dict[str, Any]:
        return dict(self.error.get("ctx") or {})


def _entry(error: Any, raw: Any) -> _Entry:
    entry = _Entry(error, ())
    data, key_path, loc = raw, [], error["loc"]
    for index, part in enumerate(loc):
        last = index == len(loc) - 1
        if _has(data, part):
            key_path.append(part)
            data, entry.via_union = data[part], False
        elif part == "[key]":
            entry.about_key = True
        elif last and error["type"] == "missing":
            entry.short_list = isinstance(data, list)
            if not entry.short_list:
                key_path.append(part)
        else:
            entry.via_union = True
    entry.key_path = tuple(key_path)
    if entry.type in ("union_tag_invalid", "union_tag_not_found"):
        entry.key_path += (_discriminator(entry),)
    return entry


def _has(data: Any, key: Any) -> bool:
    if isinstance(data, dict):
        return key in data
    return isinstance(data, list) and isinstance(key, int) and 0 <= key < len(data)


def translate(error: ValidationError, raw: dict[Any, Any], locate: Locator) -> list[Problem]:
    """One `Problem` per wrong key path, in file order."""
    entries = [_entry(e, raw) for e in error.errors(include_url=False)]
    entries = _drop_shadowed(entries)
    groups: dict[KeyPath, list[_Entry]] = {}
    for entry in entries:
        groups.setdefault(entry.key_path, []).append(entry)
    problems = []
    for key_path, group in groups.items():
        union = len(group) > 1 and all(e.via_union for e in group)
        message, hint = _combined(group, raw) if union else _single(group[0], raw)
        problems.append(Problem(key_path, message, hint, *locate(key_path)))
    return sorted(problems, key=lambda p: (p.line, p.column))


def _drop_shadowed(entries: list[_Entry]) -> list[_Entry]:
    """A union member that rejected the value outright is noise when another member got further in.

    `mirror: {left: L}` fails both as the literal "auto" and as tokens missing `right`; only the
    second says something useful.
    """

    def deeper(entry: _Entry) -> bool:
        size = len(entry.key_path)
        return any(len(o.key_path) > size and o.key_path[:size] == entry.key_path for o in entries)

    return [e for e in entries if not (e.via_union and deeper(e))]


def _single(entry: _Entry, raw: Any) -> tuple[str, str | None]:
    owner, info = _field_context(entry.key_path, raw)
    description = info.description if info is not None else None
    value = entry.error.get("input")
    kind, ctx = entry.type, entry.ctx
    if kind == "extra_forbidden":
        key = entry.key_path[-1]
        valid = list(owner.model_fields) if owner is not None else []
        return f"unknown key {key!r}", _suggest(str(key), valid, "valid keys")
    if kind == "missing":
        return _missing(entry, raw, description)
    if kind == "literal_error":
        allowed = _QUOTED.findall(str(ctx.get("expected", "")))
        if entry.about_key:
            return f"unknown key {value!r}", _suggest(str(value), allowed, "valid keys")
        shown = (
            f"unknown value {value!r}"
            if isinstance(value, str)
            else f"expected one of the allowed values, got {describe(value)}"
        )
        return shown, _suggest(str(value), allowed, "allowed values")
    if kind == "manifest_rule":
        return str(entry.error["msg"]), ctx.get("hint")
    if kind == "invalid_key":  # `5: x`: YAML read the key as a number
        key = entry.key_path[-1] if entry.key_path else value
        valid = list(owner.model_fields) if owner is not None else []
        return f"a key must be a name, got {describe(key)}", _suggest(str(key), valid, "valid keys")
    if kind in ("union_tag_invalid", "union_tag_not_found"):
        return _tag_problem(entry)
    if kind in _EXPECTED:
        return f"expected {_EXPECTED[kind]}, got {describe(value)}", _type_hint(kind, value, ctx, description)
    if kind in _BOUNDS:
        name, symbol = _BOUNDS[kind]
        return f"must be {symbol} {_number(ctx[name])}, got {describe(value)}", description
    if kind in ("too_short", "too_long"):
        limit = ctx.get("min_length", ctx.get("max_length"))
        if ctx.get("field_type") == "Tuple":
            return f"expected {limit} values, got {ctx.get('actual_length')}", description
        need = "at least" if kind == "too_short" else "at most"
        return (
            f"needs {need} {limit} item{'s' if limit != 1 else ''}, got {ctx.get('actual_length')}",
            description,
        )
    return str(entry.error["msg"]), description


def _missing(entry: _Entry, raw: Any, description: str | None) -> tuple[str, str | None]:
    if entry.short_list:
        given = _value_at(raw, entry.key_path)
        size = len(get_args(_member_for(_annotation_at(entry.key_path, raw), given)))
        return f"expected {size} values, got {len(given)}", description
    key = entry.key_path[-1]
    return f"required key {key!r} is missing", f"add `{key}:`" + (f" ({description})" if description else "")


def _type_hint(kind: str, value: object, ctx: dict[str, Any], description: str | None) -> str | None:
    if kind == "string_type" and isinstance(value, int | float) and not isinstance(value, bool):
        return f'quote it to make it text: "{value}"'
    if kind == "model_type" and isinstance(value, str) and ctx.get("class_name") == "ClipEntry":
        return f"write each clip as a mapping: `- path: {value}`"
    return description


def _discriminator(entry: _Entry) -> str:
    return str(entry.ctx.get("discriminator", "kind")).strip("'")


def _tag_problem(entry: _Entry) -> tuple[str, str | None]:
    key = _discriminator(entry)
    allowed = list(LAYER_KINDS)
    if entry.type == "union_tag_not_found":
        return f"required key {key!r} is missing", f"add `{key}:` with one of: {', '.join(allowed)}"
    tag = str(entry.ctx.get("tag"))
    return f"unknown {key} {tag!r}", _suggest(tag, allowed, "allowed values")


def _combined(group: list[_Entry], raw: Any) -> tuple[str, str | None]:
    """Several union members rejected one value: say everything that would have been accepted."""
    pieces: list[str] = []
    allowed: list[str] = []
    for entry in group:
        if entry.type == "literal_error":
            values = _QUOTED.findall(str(entry.ctx.get("expected", "")))
            allowed += values
            pieces.append("one of " + ", ".join(repr(v) for v in values))
        elif entry.type in _BOUNDS:
            name, symbol = _BOUNDS[entry.type]
            pieces.append(f"a number {symbol} {_number(entry.ctx[name])}")
        else:
            pieces.append(_EXPECTED.get(entry.type, str(entry.error["msg"])))
    value = group[0].error.get("input")
    _, info = _field_context(group[0].key_path, raw)
    hint = _suggest(str(value), allowed, "allowed values") if allowed and isinstance(value, str) else None
    return f"expected {' or '.join(dict.fromkeys(pieces))}, got {describe(value)}", hint or (
        info.description if info is not None else None
    )


def _suggest(word: str, choices: list[str], label: str) -> str:
    close = difflib.get_close_matches(word, choices, n=1)
    listing = f"{label}: {', '.join(choices)}"
    return f"did you mean {close[0]!r}? {listing}" if close else listing


def _number(value: object) -> str:
    if isinstance(value, int) and abs(value) >= 10**15:
        return f"a {len(str(abs(value)))}-digit number"  # never print 1,000 digits into a message
    return f"{value:g}" if isinstance(value, float) else str(value)


def describe(value: object) -> str:
    """A YAML-flavoured description of a value, for "expected X, got Y"."""
    if value is None:
        return "an empty value"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int | float):
        return f"the number {value}"
    if isinstance(value, str):
        return f"the text {value!r}"
    if isinstance(value, dict):
        return "a mapping"
    return "a list" if isinstance(value, list) else f"a {type(value).__name__}"


def _value_at(raw: Any, key_path: KeyPath) -> Any:
    data = raw
    for key in key_path:
        data = data[key]
    return data


def _annotation_at(key_path: KeyPath, raw: Any) -> Any:
    _, info = _field_context(key_path, raw)
    return info.annotation if info is not None else Any


def _field_context(key_path: KeyPath, raw: Any) -> tuple[type[BaseModel] | None, FieldInfo | None]:
    """The model that owns the last key of ``key_path`` and that field's info (for valid keys, docs)."""
    annotation: Any = Manifest
    data, owner, info = raw, None, None
    for key in key_path:
        annotation = _member_for(annotation, data)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            owner = annotation
            info = annotation.model_fields.get(key) if isinstance(key, str) else None
            if info is None:
                return owner, None
            annotation = info.annotation
        else:
            owner, annotation = None, _item_type(annotation, key)
        data = _child(data, key)
    return owner, info


def _child(data: Any, key: str | int) -> Any:
    if isinstance(data, dict):
        return data.get(key)
    if isinstance(data, list) and isinstance(key, int) and 0 <= key < len(data):
        return data[key]
    return None


def _item_type(annotation: Any, key: str | int) -> Any:
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is dict:
        return args[1]
    if origin is tuple and isinstance(key, int) and args:
        return args[min(key, len(args) - 1)]
    return args[0] if args else Any


def _member_for(annotation: Any, data: Any) -> Any:
    """Unwrap Annotated/Optional/unions to the member that fits ``data`` (layers by their `kind`)."""
    while get_origin(annotation) is Annotated:
        annotation = get_args(annotation)[0]
    if get_origin(annotation) not in (Union, UnionType):
        return annotation
    members = [m for m in get_args(annotation) if m is not type(None)]
    if isinstance(data, dict):
        models = [m for m in members if isinstance(m, type) and issubclass(m, BaseModel)]
        for model in models:
            kind = model.model_fields.get("kind")
            if kind is not None and data.get("kind") in get_args(kind.annotation):
                return model
        if models:
            return models[0]
    containers = [m for m in members if get_origin(m) in (list, tuple, dict)]
    if isinstance(data, list) and containers:
        return containers[0]
    return _member_for(members[0], data) if members else Any


__all__ = [
    "MAX_NODES",
    "KeyPath",
    "LoadedManifest",
    "ManifestProblemsError",
    "Problem",
    "load_manifest",
    "locate_in",
]
