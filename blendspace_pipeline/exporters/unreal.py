"""Unreal Engine 5: a Python script for the editor that creates the `BlendSpace` asset.

Blend spaces are binary `.uasset` packages, so the export is a script run inside the editor
(Tools > Execute Python Script). It sets both axes (name, range, grid divisions, snap to grid)
and one sample per clip at its snapped position. Unreal triangulates by itself — Delaunay in
min/max-normalised space, as we do — but only rebuilds that triangulation on an edit
(engines.md §1.7): the script sets everything through ``set_editor_property``, which sends the
editor's change notifications as a hand edit does, before it saves. The user maps source clip names to imported assets in the ``ANIMATIONS`` table at the
top of the script; generated clips are imported by the script from the GLBs the build wrote.
The script is safe headless (commandlet, CI): no dialogs, every asset checked before the blend
space is touched, the result read back before saving, and a non-zero exit on any failure.
"""

from __future__ import annotations

from pathlib import Path

from blendspace_pipeline import __version__
from blendspace_pipeline.exporters import Convention, EngineSpace, ExportContext, duplicate_positions, rounded

# Left-handed, Z up, centimetres, degrees: positive yaw turns right (clockwise seen from above)
# and +Y is the character's right, so handed features flip sign and speeds become cm/s.
CONVENTION = Convention(
    engine="Unreal",
    length_unit="cm",
    metres_to_length=100.0,
    angle_unit="deg",
    degrees_to_angle=1.0,
    left_positive=False,
    handedness="left-handed, Z up, centimetres, degrees",
)
SUFFIX = "_unreal.py"
REPLACES = (
    "a script this tool wrote"  # what an existing --out may be (`replaceable`); anything else is refused
)


def replaceable(text: str) -> bool:
    """Whether an existing --out file is this engine's file of a blend space, one a re-export
    may replace (keeping what the engine added to it); any other file is the user's."""
    return "Written by blendspace-pipeline" in text


LAYER_ADVICE = (
    "build them in the Animation Blueprint: a second Blend Space mixed by a Blend node (alpha = beta), "
    "a Blend Space 1D over speed mixed by Layered Blend per Bone for a style"
)
ANIMATION_FOLDER = "/Game/Animations"

_TEMPLATE = '''"""Create the Unreal blend space {name!r} from {source!r}.

Written by blendspace-pipeline {version}; Unreal Engine 5.1 or later (glTF import by Interchange).
Run it in the editor (Tools > Execute Python Script, or `py "{file_hint}"` in the Output Log) or
headless: UnrealEditor-Cmd Project.uproject -run=pythonscript -script="{file_hint}" -unattended

Before running:
  1. Import the source clips (FBX) for SKELETON and set their asset paths in ANIMATIONS.
  2. Set SKELETON, PACKAGE_PATH and ASSET_NAME.
The script imports the generated clips (GENERATED, GLB files the build wrote) onto SKELETON,
checks every clip and the skeleton before touching the asset, sets axes and samples through the
editor's property notifications (which rebuild the blend space's runtime sample data), reads the
result back, and only then saves. Any missing or mismatched asset stops it with an error.
"""

import sys

import unreal

# --- edit these ---------------------------------------------------------------------------
SKELETON = "/Game/Characters/Mannequins/Meshes/SK_Mannequin"  # the skeleton asset of your clips
PACKAGE_PATH = "/Game/BlendSpaces"
ASSET_NAME = {asset!r}
# Clip name -> animation asset path (the clips must be imported first).
ANIMATIONS = {{
{animations}
}}
# Generated clip name -> GLB file written by the build; imported into GENERATED_PATH.
GENERATED_PATH = "/Game/Animations/Generated"
GENERATED = {{
{generated}
}}

# --- written by blendspace-pipeline: axes and samples in Unreal units ---------------------
# (display name, min, max, grid divisions)
AXES = [
{axes}
]
# (clip name, x, y): every sample sits on a grid point of AXES.
SAMPLES = [
{samples}
]
# Clip name -> [(marker, seconds)]: the feet's foot-down events the build measured, written as
# sync markers on their own notify track so a blend space set to marker-based sync keeps the
# feet in step (Unreal's sync groups match LeftFootDown/RightFootDown across clips).
SYNC_TRACK = "blendspace_sync"
SYNC_MARKERS = {{
{markers}
}}


def fail(message):
    unreal.log_error(message)
    raise RuntimeError(message)


def load_skeleton():
    skeleton = unreal.load_asset(SKELETON)
    if skeleton is None:
        fail(f"skeleton not found: {{SKELETON}} (set SKELETON to the skeleton asset of your clips)")
    return skeleton


def import_generated(skeleton):
    """Import each generated GLB as an animation of SKELETON; returns name -> asset path."""
    paths = {{}}
    for name, filename in GENERATED.items():
        task = unreal.AssetImportTask()
        task.set_editor_property("filename", filename)
        task.set_editor_property("destination_path", GENERATED_PATH)
        task.set_editor_property("destination_name", name)
        task.set_editor_property("automated", True)  # no dialogs: safe headless
        task.set_editor_property("replace_existing", True)
        task.set_editor_property("save", True)
        if hasattr(unreal, "InterchangeGenericAssetsPipeline"):
            pipeline = unreal.InterchangeGenericAssetsPipeline()
            common = pipeline.get_editor_property("common_skeletal_meshes_and_animations_properties")
            common.set_editor_property("skeleton", skeleton)
            common.set_editor_property("import_only_animations", True)
            task.set_editor_property("options", pipeline)
        unreal.AssetToolsHelpers.get_asset_tools().import_asset_tasks([task])
        sequences = [
            path for path in task.get_editor_property("imported_object_paths")
            if isinstance(unreal.load_asset(path), unreal.AnimSequence)
        ]
        if not sequences:
            fail(f"generated clip {{name}}: importing {{filename}} made no animation sequence")
        paths[name] = sequences[0]
    return paths


def load_animations(skeleton, generated):
    found = {{}}
    problems = []
    for name, path in {{**ANIMATIONS, **generated}}.items():
        asset = unreal.load_asset(path)
        if asset is None:
            problems.append(f"{{name}}: {{path}} not found")
        elif asset.get_editor_property("skeleton") != skeleton:
            problems.append(f"{{name}}: {{path}} is not an animation of {{SKELETON}}")
        found[name] = asset
    missing = [name for name, _, _ in SAMPLES if name not in found]
    problems += [f"{{name}}: no asset path in ANIMATIONS" for name in missing]
    if problems:
        listing = "; ".join(problems)
        fail(f"animation assets missing or wrong (import them, then fix ANIMATIONS): {{listing}}")
    return found


def create_blend_space(skeleton):
    path = f"{{PACKAGE_PATH}}/{{ASSET_NAME}}"
    if unreal.EditorAssetLibrary.does_asset_exist(path):
        return unreal.load_asset(path)
    factory = unreal.BlendSpaceFactoryNew()
    factory.set_editor_property("target_skeleton", skeleton)
    tools = unreal.AssetToolsHelpers.get_asset_tools()
    blend_space = tools.create_asset(ASSET_NAME, PACKAGE_PATH, unreal.BlendSpace, factory)
    if blend_space is None:
        fail(f"could not create {{path}}")
    return blend_space


def set_axes(blend_space):
    parameters = list(blend_space.get_editor_property("blend_parameters"))
    for parameter, (label, low, high, divisions) in zip(parameters, AXES):
        parameter.set_editor_property("display_name", label)
        parameter.set_editor_property("min", low)
        parameter.set_editor_property("max", high)
        parameter.set_editor_property("grid_num", divisions)
        parameter.set_editor_property("snap_to_grid", True)
        parameter.set_editor_property("wrap_input", False)
    # set_editor_property sends the editor's change notifications: the blend space rebuilds its
    # runtime data (triangulation) from the new axes, as when edited by hand.
    blend_space.set_editor_property("blend_parameters", parameters)
    # Weights from the triangulation, as blendspace-pipeline evaluates them, not from the grid.
    blend_space.set_editor_property("interpolate_using_grid", False)


def set_samples(blend_space, animations):
    samples = []
    for name, x, y in SAMPLES:
        sample = unreal.BlendSample()
        sample.set_editor_property("animation", animations[name])
        sample.set_editor_property("sample_value", unreal.Vector(x, y, 0.0))
        sample.set_editor_property("rate_scale", 1.0)
        samples.append(sample)
    blend_space.set_editor_property("sample_data", samples)


def validate(blend_space, animations):
    """Read the asset back: every sample, at its place, with its clip; else stop before saving."""
    stored = list(blend_space.get_editor_property("sample_data"))
    if len(stored) != len(SAMPLES):
        fail(f"{{ASSET_NAME}} kept {{len(stored)}} of {{len(SAMPLES)}} samples (duplicate positions?)")
    for sample, (name, x, y) in zip(stored, SAMPLES):
        value = sample.get_editor_property("sample_value")
        if sample.get_editor_property("animation") != animations[name] or (value.x, value.y) != (x, y):
            fail(f"{{ASSET_NAME}}: sample {{name}} did not keep its clip or position ({{x}}, {{y}})")


def add_sync_markers(animations):
    """Replace the markers of our track on every clip that has measured foot-downs."""
    for name, markers in SYNC_MARKERS.items():
        library = unreal.AnimationLibrary
        sequence = animations[name]
        if not isinstance(sequence, unreal.AnimSequence):
            fail(f"{{name}} is not an animation sequence; sync markers need one")
        if library.is_valid_anim_notify_track_name(sequence, SYNC_TRACK):
            library.add_animation_notify_track(sequence, SYNC_TRACK)  # the track is new
        else:
            library.remove_animation_sync_markers_by_track(sequence, SYNC_TRACK)
        for marker, time in markers:
            library.add_animation_sync_marker(sequence, marker, time, SYNC_TRACK)
        if not unreal.EditorAssetLibrary.save_loaded_asset(sequence, False):
            fail(f"could not save the sync markers of {{name}}")


def headless():
    line = unreal.SystemLibrary.get_command_line().lower()
    return "-run=" in line or "-unattended" in line or "-nullrhi" in line


def main():
    skeleton = load_skeleton()
    generated = import_generated(skeleton)
    animations = load_animations(skeleton, generated)
    add_sync_markers(animations)
    blend_space = create_blend_space(skeleton)
    blend_space.modify()
    set_axes(blend_space)
    set_samples(blend_space, animations)
    validate(blend_space, animations)
    if not unreal.EditorAssetLibrary.save_loaded_asset(blend_space, False):
        fail(f"could not save {{PACKAGE_PATH}}/{{ASSET_NAME}}")
    if not headless():
        unreal.get_editor_subsystem(unreal.AssetEditorSubsystem).open_editor_for_assets([blend_space])
    unreal.log(f"{{ASSET_NAME}}: {{len(SAMPLES)}} samples set and saved")


try:
    main()
except RuntimeError:
    if headless():
        sys.exit(1)  # a commandlet run fails with a non-zero exit code
    raise
'''


def render(space: EngineSpace, context: ExportContext) -> tuple[str, list[str], dict[Path, str]]:
    animations = "\n".join(
        f"    {s.name!r}: {f'{ANIMATION_FOLDER}/{s.name}'!r}," for s in space.samples if not s.generated
    )
    glbs = {s.name: _glb(s.name, context) for s in space.samples if s.generated}
    generated = "\n".join(f"    {name!r}: {str(path)!r}," for name, path in glbs.items() if path)
    axes = "\n".join(
        f"    ({a.label!r}, {_float(a.minimum)}, {_float(a.maximum)}, {a.divisions})," for a in space.axes
    )
    samples = "\n".join(
        f"    ({s.name!r}, {_float(s.position[0])}, {_float(s.position[1])})," for s in space.samples
    )
    markers = "\n".join(
        f"    {s.name!r}: [{', '.join(f'({m!r}, {_float(t)})' for m, t in s.markers)}],"
        for s in space.samples
        if s.markers
    )
    text = _TEMPLATE.format(
        name=space.name,
        source=space.source or f"{space.name}.blendspace.json",
        version=__version__,
        file_hint=f"{space.name}{SUFFIX}",
        asset=f"BS_{space.name}",
        animations=animations,
        generated=generated,
        axes=axes,
        samples=samples,
        markers=markers,
    )
    missing = [name for name, path in glbs.items() if path is None]
    notes = _notes(space)
    if missing:
        notes.append(
            f"generated clips without a GLB ({', '.join(missing)}): rebuild with `glb` in output.clip_formats, "
            "or import them by hand and add them to ANIMATIONS"
        )
    return text, notes, {}


def _glb(name: str, context: ExportContext) -> Path | None:
    return next((p for p in context.clip_files.get(name, []) if p.suffix.lower() == ".glb"), None)


def _float(value: float) -> str:
    """Python float literal: Unreal's float properties get floats, not ints."""
    return repr(rounded(value))


def _notes(space: EngineSpace) -> list[str]:
    notes = [
        f"set SKELETON and the animation asset paths in ANIMATIONS (default {ANIMATION_FOLDER}/<clip>) "
        "before running the script in the Unreal editor",
        "Unreal rebuilds its triangulation itself (Delaunay on min/max-normalised axes, like ours; grid ties "
        "split by its Tangential rule); the script sets the data through editor notifications so it does",
    ]
    duplicates = duplicate_positions(space)
    if duplicates:
        pairs = ", ".join(f"{a} = {b}" for a, b in duplicates)
        notes.append(f"Unreal rejects samples at the same position; it will drop one of: {pairs}")
    return notes
