"""Loading, configuring and running rules.

Rules come from four places, all through `load_rules`, in this order: the built-in package
`blendspace_pipeline.rules` (the top-level `rules/` folder), the entry-point group
`blendspace_pipeline.rules`, the folders in `BLENDSPACE_RULE_PATH`, and the manifest's
`plugins:` (module names or paths). A plugin that fails to import or repeats a slug becomes a
visible `plugin-error` diagnostic naming its source: never a silent skip.

Trust model (a pre-commit hook or a build farm runs on changes nobody has reviewed yet): built-in
rules and installed entry points are trusted, they are installed software. `plugins:` and
`BLENDSPACE_RULE_PATH` run code named by the manifest or the environment, so a plugin given by
path loads only from inside the manifest's project (its folder tree, symlinks resolved): a
manifest cannot run `/abs/evil.py` or `../outside/evil.py`. For an untrusted run, `--no-plugins`
on build and check, or `BLENDSPACE_NO_PLUGINS=1`, loads neither `plugins:` nor
`BLENDSPACE_RULE_PATH`; `rules:` naming a rule that is then missing is a warning, not an error.

Each run makes fresh rule instances with their validated options, and hands them read-only views;
whatever a rule yields is checked (`finding_problem`) before it can reach the outputs or a fix.
"""

from __future__ import annotations

import contextlib
import difflib
import importlib
import importlib.util
import inspect
import math
import numbers
import os
import pkgutil
import re
import sys
import traceback
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from importlib.metadata import entry_points
from pathlib import Path
from types import ModuleType

from pydantic import BaseModel, ValidationError

from blendspace_pipeline.api import (
    DetectionGuessView,
    LayerView,
    Rule,
    RuleOptions,
    SampleView,
    SpaceView,
    iter_rule_classes,
)
from blendspace_pipeline.checks.trust import plugins_disabled
from blendspace_pipeline.diagnostics import SEVERITY_ORDER, Diagnostic, Placeholder, Severity
from blendspace_pipeline.space.model import BetaSpace, BlendSpace, Layer, MeasuredClip

ENTRY_POINT_GROUP = "blendspace_pipeline.rules"
RULE_PATH_VARIABLE = "BLENDSPACE_RULE_PATH"


ENGINE_CODES = {
    "plugin-error": "BS900",
    "unused-suppression": "BS901",
    "rule-crashed": "BS902",
    "unknown-rule": "BS906",  # BS903/BS904/BS907: fix_loop; BS905: invalid-input (commands)
}
_WARNINGS = {"unused-suppression", "unknown-rule"}
# The engine's own findings (here, in fix_loop and in the commands) own these names: a plugin rule
# taking one would make `ignore:` and the reports ambiguous.
RESERVED_SLUGS = frozenset(ENGINE_CODES) | {"fix-skipped", "fix-removed", "fix-rejected", "invalid-input"}
RESERVED_CODE_PREFIX = "BS9"


@dataclass
class LoadedRules:
    rules: dict[str, type[Rule]] = field(default_factory=dict)  # slug -> class
    origins: dict[str, str] = field(default_factory=dict)  # slug -> where it came from
    problems: list[Diagnostic] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)  # plugins not loaded because plugins are off

    def add_module(self, module: ModuleType, origin: str) -> None:
        for rule in iter_rule_classes(vars(module)):
            if rule.__module__ != module.__name__:
                continue  # imported into the module, defined elsewhere
            self.add(rule, origin)

    def add(self, rule: type[Rule], origin: str) -> None:
        problem = rule_problem(rule)
        if problem is not None:
            self.problems.append(
                _engine_diagnostic("plugin-error", f"rule {rule.__name__} from {origin} {problem}")
            )
            return
        if rule.slug in RESERVED_SLUGS or rule.code.startswith(RESERVED_CODE_PREFIX):
            self.problems.append(
                _engine_diagnostic(
                    "plugin-error",
                    f"rule {rule.slug} ({rule.code}) from {origin} uses a name the engine keeps for "
                    "its own findings; it is not loaded",
                    hint=f"engine codes start with {RESERVED_CODE_PREFIX}; pick another slug or code",
                )
            )
            return
        if rule.slug in self.rules:
            self.problems.append(
                _engine_diagnostic(
                    "plugin-error",
                    f"duplicate rule slug {rule.slug!r}: {origin} repeats the rule from {self.origins[rule.slug]}; "
                    "the first one is kept",
                )
            )
            return
        taken = next((slug for slug, known in self.rules.items() if known.code == rule.code), None)
        if taken is not None:  # `select`, `ignore` and `severity` by code must name one rule
            self.problems.append(
                _engine_diagnostic(
                    "plugin-error",
                    f"duplicate rule code {rule.code!r}: {rule.slug} from {origin} repeats the code of "
                    f"{taken} from {self.origins[taken]}; the first one is kept",
                    hint="give the plugin rule its own code (studios use their own prefix, e.g. ST001)",
                )
            )
            return
        self.rules[rule.slug] = rule
        self.origins[rule.slug] = origin

    def by_code(self) -> dict[str, str]:
        return {rule.code: slug for slug, rule in self.rules.items()}


_UNNAMEABLE = re.compile("[\x00-\x1f\x7f-\x9f]|^\\s|\\s$")


def rule_problem(rule: type[Rule]) -> str | None:
    """Why the loader refuses ``rule`` (as "is incomplete ...", "has bad Options ..."), or None."""
    missing = [a for a in ("slug", "code", "severity", "summary") if not hasattr(rule, a)]
    if (
        missing
        or not isinstance(rule.slug, str)
        or not isinstance(rule.code, str)
        or rule.severity not in ("error", "warning", "info")
    ):
        return "is incomplete (needs slug, code, severity error|warning|info, summary)"
    if any(not name.strip() or _UNNAMEABLE.search(name) for name in (rule.slug, rule.code)):
        # A manifest names rules by slug or code (`select`, `ignore`, per-clip `ignore:`): an empty
        # one was a blank row in `blendspace rules`. Any other text can be written in YAML.
        return f"has slug {rule.slug!r} and code {rule.code!r}: both must be non-empty text without control characters"
    problem = _options_problem(rule.Options)
    return None if problem is None else f"has bad Options: {problem}"


def _options_problem(model: object) -> str | None:
    """Options must be checkable (unknown keys rejected) and optional (a default for each field)."""
    if model is None:
        return None
    if not (isinstance(model, type) and issubclass(model, BaseModel)):
        return "it must be a RuleOptions subclass (a pydantic model)"
    if model.model_config.get("extra") != "forbid":
        # Otherwise a misspelt option in the manifest would be silently ignored.
        return "it must forbid unknown keys (derive from RuleOptions, or set extra='forbid')"
    for name, info in model.model_fields.items():
        if info.is_required():
            return f"option {name!r} needs a default (a manifest need not set any option)"
        if not info.description:
            return f"option {name!r} needs a description (`blendspace rules` prints it)"
    try:
        # Options come from YAML: their defaults must be plain data `blendspace rules` can print.
        model().model_dump(mode="json")
    except Exception as error:
        return f"its defaults do not validate or serialise: {type(error).__name__}: {error}"
    return None


def _engine_diagnostic(slug: str, message: str, hint: str | None = None) -> Diagnostic:
    return Diagnostic(
        rule=slug,
        code=ENGINE_CODES[slug],
        severity="warning" if slug in _WARNINGS else "error",
        message=message,
        hint=hint,
    )


def _import_failure(origin: str, error: BaseException, path: Path | None = None) -> Diagnostic:
    last = traceback.format_exception_only(type(error), error)[-1].strip()
    return _engine_diagnostic(
        "plugin-error",
        f"{origin} failed to import: {last}{_where(error, path)}",
        hint="fix the plugin or remove it from `plugins:` / BLENDSPACE_RULE_PATH",
    )


def _where(error: BaseException, path: Path | str | None) -> str:
    """` (file:line)` of the plugin's own line that failed: a syntax error's, else the last frame
    of the traceback inside ``path`` (the plugin's file). Empty when neither is known."""
    if isinstance(error, SyntaxError) and error.filename and error.lineno:
        return f" ({error.filename}:{error.lineno})"
    if path is None:
        return ""
    inside = [f for f in traceback.extract_tb(error.__traceback__) if Path(f.filename) == Path(path)]
    return f" ({inside[-1].filename}:{inside[-1].lineno})" if inside else ""


def _load_path(path: Path, loaded: LoadedRules, origin: str) -> None:
    module_name = f"blendspace_plugin_{abs(hash(str(path.resolve()))):x}_{path.stem}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        loaded.problems.append(_engine_diagnostic("plugin-error", f"{origin} is not a Python file"))
        return
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    # `check` writes nothing: no __pycache__ folder may appear beside a studio's rule files.
    writes_bytecode = sys.dont_write_bytecode
    sys.dont_write_bytecode = True
    try:
        with contextlib.redirect_stdout(sys.stderr):  # a plugin's print must not corrupt --format json
            spec.loader.exec_module(module)
    except KeyboardInterrupt:
        raise
    except BaseException as error:  # even sys.exit: a broken plugin is a diagnostic, never a crash or an exit
        sys.modules.pop(module_name, None)
        loaded.problems.append(_import_failure(origin, error, path))
        return
    finally:
        sys.dont_write_bytecode = writes_bytecode
    loaded.add_module(module, origin)


def _load_module_name(name: str, loaded: LoadedRules, origin: str) -> None:
    """Import plugin module ``name`` from the installed packages: not from the working folder,
    which `python -m blendspace_pipeline` puts first on `sys.path` (a manifest could run a file
    from outside its project there, and the `blendspace` script would not find the same one)."""
    here = {"", os.getcwd()}
    # Only the working folder's entries are taken out, and only they are put back: what the
    # plugin adds while it imports (its vendored folder) stays, for the imports its rules make later.
    removed = [(i, e) for i, e in enumerate(sys.path) if e in here and not _installed_here(e)]
    try:
        for index, _ in reversed(removed):
            del sys.path[index]
        with contextlib.redirect_stdout(sys.stderr):  # a plugin's print must not corrupt --format json
            module = importlib.import_module(name)
    except KeyboardInterrupt:
        raise
    except BaseException as error:  # SystemExit and custom BaseExceptions too: a diagnostic, not an exit
        loaded.problems.append(_import_failure(origin, error))
        return
    finally:
        for index, entry in removed:
            sys.path.insert(min(index, len(sys.path)), entry)
    loaded.add_module(module, origin)


def _installed_here(entry: str) -> bool:
    """Whether the working folder ``entry`` is itself where packages are installed (a folder
    named on PYTHONPATH or a site folder that happens to be the working folder)."""
    named = os.environ.get("PYTHONPATH", "").split(os.pathsep)
    return bool(entry) and (
        entry in named or os.path.abspath(entry) in {os.path.abspath(n) for n in named if n}
    )


def plugin_file(plugin: str, base_dir: Path | None) -> Path | None:
    """The file a `plugins:` entry names (relative to ``base_dir``, the manifest's folder), or None
    when it names a module: a `.py` path, or an existing file, is a file (also one not there yet)."""
    candidate = Path(plugin.replace("\\", "/"))
    if not candidate.is_absolute() and base_dir is not None:
        candidate = base_dir / candidate
    return candidate if plugin.endswith(".py") or candidate.is_file() else None


def load_rules(plugins: Iterable[str] = (), base_dir: Path | None = None) -> LoadedRules:
    loaded = LoadedRules()
    package = importlib.import_module("blendspace_pipeline.rules")
    for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue  # private helpers of the built-in rules
        _load_module_name(f"blendspace_pipeline.rules.{info.name}", loaded, f"built-in rules/{info.name}.py")
    for point in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda p: p.name):
        origin = f"entry point {point.name} = {point.value}"
        try:
            target = point.load()
        except KeyboardInterrupt:
            raise
        except BaseException as error:  # as for plugin modules: a diagnostic, not an exit
            loaded.problems.append(_import_failure(origin, error))
            continue
        if isinstance(target, ModuleType):
            loaded.add_module(target, origin)
        elif isinstance(target, type) and issubclass(target, Rule):
            loaded.add(target, origin)
        else:
            loaded.problems.append(
                _engine_diagnostic("plugin-error", f"{origin} is neither a module nor a Rule")
            )
    if plugins_disabled():
        loaded.skipped += [
            f"{RULE_PATH_VARIABLE} {f}" for f in os.environ.get(RULE_PATH_VARIABLE, "").split(os.pathsep) if f
        ]
        loaded.skipped += [f"plugin {p}" for p in plugins]
        return loaded
    for folder in filter(None, os.environ.get(RULE_PATH_VARIABLE, "").split(os.pathsep)):
        directory = Path(folder)
        if not directory.is_dir():
            loaded.problems.append(
                _engine_diagnostic("plugin-error", f"{RULE_PATH_VARIABLE} folder {folder} does not exist")
            )
            continue
        for path in sorted(directory.glob("*.py")):
            _load_path(path, loaded, f"rule file {path} (from {RULE_PATH_VARIABLE})")
    for plugin in plugins:
        candidate = plugin_file(plugin, base_dir)
        if candidate is not None:
            if not candidate.is_file():
                loaded.problems.append(
                    _engine_diagnostic(
                        "plugin-error",
                        f"plugin file {plugin} not found (looked at {candidate})",
                        hint="paths in `plugins:` are relative to the manifest",
                    )
                )
                continue
            if base_dir is not None and not _inside(candidate, base_dir):
                loaded.problems.append(
                    _engine_diagnostic(
                        "plugin-error",
                        f"plugin file {plugin} lies outside the manifest's project ({candidate.resolve()}); "
                        "it was not loaded",
                        hint="keep studio rule files inside the project folder, or install them as a "
                        "package with a `blendspace_pipeline.rules` entry point",
                    )
                )
                continue
            _load_path(candidate, loaded, f"rule plugin {plugin}")
        else:
            _load_module_name(plugin, loaded, f"rule plugin {plugin}")
    return loaded


def _inside(path: Path, root: Path) -> bool:
    """Whether ``path`` (symlinks resolved) lies in ``root``'s folder tree."""
    target, base = path.resolve(), root.resolve()
    return target == base or target.is_relative_to(base)


def sample_view(
    clip: MeasuredClip,
    position: tuple[float, float],
    measured: tuple[float, float],
    normalised: tuple[float, float],
    *,
    generated: bool = False,
    fix: str | None = None,
) -> SampleView:
    m = clip.measurement
    expect = clip.entry.expect
    return SampleView(
        name=clip.name,
        source=str(clip.source),
        position=position,
        measured=measured,
        normalised=normalised,
        # SampleView freezes its mappings (api._read_only): no rule may change what the next sees.
        features={str(k): float(v) for k, v in m.features.items()},
        generated=generated,
        fix=fix,
        expect={str(k): float(v) for k, v in expect.items()} if expect else None,
        frames=m.frames,
        fps=m.fps,
        meters_per_unit=m.meters_per_unit,
        units_source=m.units_source,
        up_axis=m.up_axis,
        in_place=m.in_place,
        units_guessed=m.units_guessed,
        joint_names=tuple(m.joint_names),
        joint_parents=tuple(m.joint_parents),
        notes=tuple(m.notes),
        guesses=tuple(
            DetectionGuessView(g.what, g.value, g.evidence, g.override, g.stated) for g in m.guesses
        ),
        skeleton_key=m.skeleton_key,
        gait_period=m.gait_period,
        contacts={foot: tuple((a, b) for a, b in spans) for foot, spans in m.contacts.items()}
        if m.contacts is not None
        else None,
        plant_phases=m.plant_phases,
        partial_stride=m.partial_stride,
        up_source=m.up_source,
    )


# The sample views of the last `space_view`, by clip object: a placeholder simulation or a fix
# round runs the rules again on a space that shares almost every clip, and a view costs about
# 0.1 ms (a thousand samples: 0.1 s a run). An entry is reused only for the very same clip,
# measurement and entry objects with the same name, source, position and flags (views are
# immutable, so sharing one between runs is safe); it keeps its clip alive, so an id is never
# reused while it is remembered. Only the last view's samples are kept.
_ViewKey = tuple[object, ...]
_last_views: dict[int, tuple[MeasuredClip, _ViewKey, SampleView]] = {}


def _samples(
    space: BlendSpace, made: dict[int, tuple[MeasuredClip, _ViewKey, SampleView]] | None = None
) -> tuple[SampleView, ...]:
    normalised = space.normalised_positions()
    views = []
    for i, s in enumerate(space.samples):
        clip = s.clip
        at = (float(normalised[i, 0]), float(normalised[i, 1]))
        key: _ViewKey = (
            clip.name,
            str(clip.source),
            clip.measurement,
            clip.entry,
            tuple(s.position),
            tuple(s.measured),
            at,
            s.generated,
            s.fix,
        )
        known = _last_views.get(id(clip))
        if known is not None and known[0] is clip and _same(known[1], key):
            view = known[2]
        else:
            view = sample_view(clip, s.position, s.measured, at, generated=s.generated, fix=s.fix)
        if made is not None:
            made[id(clip)] = (clip, key, view)
        views.append(view)
    return tuple(views)


def _same(a: _ViewKey, b: _ViewKey) -> bool:
    """Equal keys, the measurement and entry compared by identity (they are not rebuilt in place)."""
    return a[2] is b[2] and a[3] is b[3] and a[:2] == b[:2] and a[4:] == b[4:]


def _layer_view(layer: Layer, made: dict[int, tuple[MeasuredClip, _ViewKey, SampleView]]) -> LayerView:
    if isinstance(layer, BetaSpace):
        return LayerView(
            layer.name, "beta", layer.space.axes, _samples(layer.space, made), axes_match=layer.axes_match
        )
    axis = layer.axis
    samples = []
    for clip, value in zip(layer.clips, layer.positions, strict=True):
        measured = float(clip.measurement.features[axis.feature])
        normalised = (value - axis.minimum) / (axis.maximum - axis.minimum) * 100.0
        samples.append(sample_view(clip, (value, 0.0), (measured, 0.0), (normalised, 0.0)))
    mask = layer.mask
    return LayerView(
        layer.name,
        "style",
        (axis,),
        tuple(samples),
        mask=mask.joints if mask is not None else None,
        mask_default=mask.default if mask is not None else 1.0,
    )


def space_view(space: BlendSpace) -> SpaceView:
    global _last_views
    made: dict[int, tuple[MeasuredClip, _ViewKey, SampleView]] = {}
    view = SpaceView(
        name=space.name,
        axes=space.axes,
        samples=_samples(space, made),
        triangles=tuple(space.triangles),
        thresholds=space.manifest.model.thresholds.model_dump(),
        layers=tuple(_layer_view(layer, made) for layer in space.layer_spaces),
    )
    _last_views = made
    return view


def _selected(slug: str, code: str, select: list[str], ignore: list[str]) -> bool:
    names = {slug, code}
    chosen = "all" in select or bool(names & set(select))
    return chosen and not (names & set(ignore))


def loaded_rules_of(space: BlendSpace) -> LoadedRules:
    """The rules loaded for this space (kept on it), loading them the first time."""
    if isinstance(space.rules, LoadedRules):
        return space.rules
    return load_rules(space.manifest.model.plugins, space.manifest.directory)


def run_rules(space: BlendSpace) -> None:
    """Run every selected rule, apply severities and suppressions, and store the results."""
    model = space.manifest.model
    loaded = loaded_rules_of(space)
    space.rules = loaded
    findings: list[Diagnostic] = list(loaded.problems)
    findings += _check_rule_names(space, loaded)
    options = _rule_options(space, loaded)
    view = space_view(space)
    by_code = loaded.by_code()
    severity_overrides = {by_code.get(key, key): value for key, value in model.rules.severity.items()}
    known_clips = known_clip_names(view)
    for slug, rule_class in loaded.rules.items():
        if not _selected(slug, rule_class.code, model.rules.select, model.rules.ignore):
            continue
        override = severity_overrides.get(slug)
        if override == "off":
            continue
        made: list[Diagnostic] = []
        try:
            # A fresh instance per run: options and severity are this manifest's, never a previous one's.
            rule = rule_class(severity=override, options=options.get(slug))
            with contextlib.redirect_stdout(sys.stderr):  # a rule's print must not corrupt --format json
                for item in rule.check(view):
                    problem = finding_problem(item, rule_class, known_clips)
                    if problem:
                        raise TypeError(problem)
                    made.append(item)
        except KeyboardInterrupt:
            raise
        except BaseException as error:  # one broken rule (even one calling sys.exit) must not hide the others
            # Its findings so far are dropped too: a half-run rule's placeholders and fixes are not trusted.
            made = [
                _engine_diagnostic(
                    "rule-crashed",
                    f"rule {slug} ({loaded.origins[slug]}) crashed: {type(error).__name__}: {error}"
                    f"{_where(error, inspect.getsourcefile(rule_class))}",
                    hint="report this to the rule's author; the other rules ran",
                )
            ]
        findings += made
    # Which names are rules is known only with every plugin loaded (not with --no-plugins).
    known = None
    if not loaded.problems and not loaded.skipped:
        known = set(loaded.rules) | set(loaded.by_code()) | set(ENGINE_CODES) | set(ENGINE_CODES.values())
    findings = _apply_clip_ignores(space, findings, known)
    space.diagnostics = sorted(space.diagnostics + findings, key=Diagnostic.sort_key)
    space.placeholders = _unique_placeholders(space.diagnostics)


def known_clip_names(view: SpaceView) -> set[str]:
    """The clip names a finding on ``view`` may name: its samples and its layers' samples."""
    names = {sample.name for sample in view.samples}
    for layer in view.layers:
        names |= {sample.name for sample in layer.samples}
    return names


def finding_problem(item: object, rule: type[Rule], known_clips: set[str]) -> str | None:
    """Why something ``rule`` yielded cannot be a finding, or None.

    Everything downstream trusts findings: JSON would carry NaN, `build` would index a missing
    clip, sorting would fail on an unknown severity, and `ignore:` would match the wrong rule.
    """
    if not isinstance(item, Diagnostic):
        return f"it yielded {type(item).__name__} {item!r:.60}, not a Diagnostic (use self.report)"
    if (item.rule, item.code) != (rule.slug, rule.code):
        return f"it yielded a finding of {item.rule} ({item.code}), not its own (use self.report)"
    if item.severity not in SEVERITY_ORDER:
        return f"it yielded severity {item.severity!r}, not error, warning or info"
    if not isinstance(item.clips, tuple) or not all(isinstance(name, str) for name in item.clips):
        return f"its clips are {item.clips!r:.60}, not a tuple of clip names"
    positions: list[object] = [item.position] if item.position is not None else []
    values: list[object] = []
    for mark in item.placeholders:
        if not isinstance(mark, Placeholder):
            return f"its placeholders hold {type(mark).__name__}, not Placeholder"
        positions.append(mark.position)
        values += mark.features.values()
    if not all(isinstance(point, tuple) and len(point) == 2 for point in positions):
        return f"it reported a position that is not an (x, y) pair: {item.message!r:.80}"
    values += [value for point in positions if isinstance(point, tuple) for value in point]
    if not all(_finite_number(value) for value in values):
        return f"it reported a position or feature that is not a finite number: {item.message!r:.80}"
    unknown = sorted(set(item.clips) - known_clips)
    if unknown:
        return f"it named clips that are not in the space: {', '.join(unknown[:5])}"
    return None


def _finite_number(value: object) -> bool:
    # A float first: the ABC check of `numbers.Real` is most of this test's time (a 1,000-clip
    # space checks ~10,000 numbers per rule run).
    return (type(value) is float or isinstance(value, numbers.Real)) and math.isfinite(value)


def _rule_key(loaded: LoadedRules, name: str) -> str | None:
    """The slug a `rules:` entry names (by slug or code), or None."""
    return name if name in loaded.rules else loaded.by_code().get(name)


def _check_rule_names(space: BlendSpace, loaded: LoadedRules) -> list[Diagnostic]:
    """Every rule named in `rules:` must exist: a typo in `select` would switch checking off.

    An unknown name is a manifest error (exit 2) at its line, unless a plugin failed to load: the
    name may be that plugin's, so it is a warning and the broken plugin is the error to fix.
    """
    settings = space.manifest.model.rules
    named: list[tuple[str, tuple[str | int, ...]]] = []
    named += [(n, ("rules", "select", i)) for i, n in enumerate(settings.select) if n != "all"]
    named += [(n, ("rules", "ignore", i)) for i, n in enumerate(settings.ignore)]
    named += [(n, ("rules", "severity", n)) for n in settings.severity]
    named += [(n, ("rules", "options", n)) for n in settings.options]
    known = sorted(set(loaded.rules) | set(loaded.by_code()))
    warnings: list[Diagnostic] = []
    configured: dict[tuple[str | int, str], str] = {}  # (section, slug) -> the name first used
    for name, key_path in named:
        slug = _rule_key(loaded, name)
        if slug is not None:
            section = key_path[1]
            first = configured.setdefault((section, slug), name)
            if section in ("severity", "options") and first != name:
                # By slug and by code at once: which value wins would be an accident of order.
                raise space.manifest.error_at(
                    key_path,
                    f"rules.{section}.{name}: {slug} is already configured as {first!r}",
                    f"keep one of {first!r} and {name!r}",
                )
            continue
        close = difflib.get_close_matches(name, known, n=1)
        hint = (f"did you mean {close[0]!r}? " if close else "") + "`blendspace rules` lists every rule"
        message = f"{'.'.join(str(k) for k in key_path)}: no rule is called {name!r}"
        if not loaded.problems and not loaded.skipped:
            raise space.manifest.error_at(key_path, message, hint)
        line, column = space.manifest.locate(key_path)
        why = " (a plugin failed to load)" if loaded.problems else " (plugins are off: --no-plugins)"
        warnings.append(
            replace(
                _engine_diagnostic("unknown-rule", message, hint=hint + why),
                path=str(space.manifest.path),
                line=line,
                column=column,
            )
        )
    return warnings


def _rule_options(space: BlendSpace, loaded: LoadedRules) -> dict[str, RuleOptions]:
    """Each configured rule's options, validated against its `Options` model (exit 2 if wrong)."""
    manifest = space.manifest
    validated: dict[str, RuleOptions] = {}
    for name, values in manifest.model.rules.options.items():
        slug = _rule_key(loaded, name)
        if slug is None:
            continue  # reported by _check_rule_names
        model = loaded.rules[slug].Options
        if model is None:
            raise manifest.error_at(
                ("rules", "options", name),
                f"rules.options.{name}: the rule {slug} takes no options",
                "remove the entry; `blendspace rules` lists each rule's options",
            )
        try:
            validated[slug] = model.model_validate(values)
        except ValidationError as error:
            first = error.errors()[0]
            where = first["loc"]  # ints stay ints: they index lists when the line is looked up
            dotted = ".".join(str(part) for part in ("rules", "options", name, *where))
            raise manifest.error_at(
                ("rules", "options", name, *where),
                f"{dotted}: {first['msg']}",
                f"the options of {slug} are: {', '.join(model.model_fields)}",
            ) from None
    return validated


def _unique_placeholders(diagnostics: list[Diagnostic]) -> list[Placeholder]:
    """One marker per position and priority: several rules may ask for the same clip."""
    seen: set[tuple[tuple[float, float], str]] = set()
    unique = []
    for diagnostic in diagnostics:
        for mark in diagnostic.placeholders:
            key = ((round(mark.position[0], 6), round(mark.position[1], 6)), mark.priority)
            if key not in seen:
                seen.add(key)
                unique.append(mark)
    return unique


def _apply_clip_ignores(
    space: BlendSpace, findings: list[Diagnostic], known: set[str] | None
) -> list[Diagnostic]:
    """Drop findings a clip's `ignore:` covers; report suppressions that matched nothing, and
    those that name no rule at all (``known``: every slug and code, None when a plugin did not
    load) with the nearest one.

    An `ignore:` belongs to a manifest entry, and a glob entry covers many clips: it is in use
    when it suppressed a finding on any of them, and reported once per entry when it did not.
    """
    kept: list[Diagnostic] = []
    used: set[tuple[int, int, str]] = set()  # (entry line, entry column, ignored rule)
    entries = {s.name: s.clip for s in space.samples}
    for finding in findings:
        suppressed = False
        for clip_name in finding.clips:
            clip = entries.get(clip_name)
            if clip is None:
                continue
            for ignore in clip.entry.ignore:
                if ignore.rule in (finding.rule, finding.code):
                    used.add((clip.line, clip.column, ignore.rule))
                    suppressed = True
        if not suppressed:
            kept.append(finding)
    by_entry: dict[tuple[int, int], list[str]] = {}
    for name, clip in entries.items():
        by_entry.setdefault((clip.line, clip.column), []).append(name)
    for (line, column), names in by_entry.items():
        entry = entries[names[0]].entry
        for ignore in entry.ignore:
            if (line, column, ignore.rule) in used:
                continue
            whom = (
                f"clip {names[0]!r}" if len(names) == 1 else f"the entry {entry.path!r} ({len(names)} clips)"
            )
            if (
                known is not None and ignore.rule not in known
            ):  # a typo: in `rules:` it is exit 2, here a warning at the entry
                close = difflib.get_close_matches(ignore.rule, sorted(known), n=1)
                kept.append(
                    replace(
                        _engine_diagnostic(
                            "unknown-rule",
                            f"{whom} ignores {ignore.rule!r}, which is not a rule",
                            hint=(f"did you mean {close[0]!r}? " if close else "")
                            + "`blendspace rules` lists every rule",
                        ),
                        clips=(names[0],),
                    )
                )
                continue
            kept.append(
                replace(
                    _engine_diagnostic(
                        "unused-suppression",
                        f"{whom} ignores {ignore.rule!r} but that rule reported nothing on it",
                        hint="remove the stale `ignore:` entry (or check the rule slug)",
                    ),
                    clips=(names[0],),
                )
            )
    return kept


def severity_of(diagnostics: Iterable[Diagnostic]) -> set[Severity]:
    return {d.severity for d in diagnostics}
