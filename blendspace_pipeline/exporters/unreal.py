"""Unreal Engine 5: a Python script for the editor that creates the `BlendSpace` asset.

Blend spaces are binary `.uasset` packages, so the export is a script run inside the editor
(Tools > Execute Python Script). It sets both axes (name, range, grid divisions, snap to grid)
and one sample per clip at its snapped position. Unreal triangulates by itself — Delaunay in
min/max-normalised space, as we do — but only rebuilds that triangulation when the asset is
opened or edited in the Blend Space editor (engines.md §1.7): the script opens it and the user
saves it. Animation assets cannot be created from here; the user maps clip names to imported
assets in the ``ANIMATIONS`` table at the top of the script.
"""

from __future__ import annotations

from blendspace_pipeline import __version__
from blendspace_pipeline.exporters import Convention, EngineSpace, duplicate_positions, rounded

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
LAYER_ADVICE = (
    "build them in the Animation Blueprint: a second Blend Space mixed by a Blend node (alpha = beta), "
    "a Blend Space 1D over speed mixed by Layered Blend per Bone for a style"
)
ANIMATION_FOLDER = "/Game/Animations"

_TEMPLATE = '''"""Create the Unreal blend space {name!r} from {source!r}.

Written by blendspace-pipeline {version}; Unreal Engine 5.0 or later. Run it in the editor
(Tools > Execute Python Script, or `py "{file_hint}"` in the Output Log).

Before running:
  1. Import the animation clips (FBX) for SKELETON and set their asset paths in ANIMATIONS.
  2. Set SKELETON, PACKAGE_PATH and ASSET_NAME.
After running:
  3. The script opens the asset in the Blend Space editor; Unreal rebuilds the triangulation
     only there (a blend space written by a script alone evaluates to the reference pose).
     Check the samples, then save the asset (Ctrl+S).
"""

import unreal

# --- edit these ---------------------------------------------------------------------------
SKELETON = "/Game/Characters/Mannequins/Meshes/SK_Mannequin"  # the skeleton asset of your clips
PACKAGE_PATH = "/Game/BlendSpaces"
ASSET_NAME = {asset!r}
# Clip name -> animation asset path (the clips must be imported first).
ANIMATIONS = {{
{animations}
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


def load_animations():
    found = {{}}
    missing = []
    for name, path in ANIMATIONS.items():
        asset = unreal.load_asset(path)
        if asset is None:
            missing.append(f"{{name}}: {{path}}")
        found[name] = asset
    if missing:
        listing = "; ".join(missing)
        raise RuntimeError(f"animation assets not found (import them, then fix ANIMATIONS): {{listing}}")
    return found


def create_blend_space():
    path = f"{{PACKAGE_PATH}}/{{ASSET_NAME}}"
    if unreal.EditorAssetLibrary.does_asset_exist(path):
        return unreal.load_asset(path)
    factory = unreal.BlendSpaceFactoryNew()
    factory.set_editor_property("target_skeleton", unreal.load_asset(SKELETON))
    tools = unreal.AssetToolsHelpers.get_asset_tools()
    return tools.create_asset(ASSET_NAME, PACKAGE_PATH, unreal.BlendSpace, factory)


def set_axes(blend_space):
    parameters = list(blend_space.get_editor_property("blend_parameters"))
    for parameter, (label, low, high, divisions) in zip(parameters, AXES):
        parameter.set_editor_property("display_name", label)
        parameter.set_editor_property("min", low)
        parameter.set_editor_property("max", high)
        parameter.set_editor_property("grid_num", divisions)
        parameter.set_editor_property("snap_to_grid", True)
        parameter.set_editor_property("wrap_input", False)
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


def main():
    animations = load_animations()
    blend_space = create_blend_space()
    set_axes(blend_space)
    set_samples(blend_space, animations)
    unreal.EditorAssetLibrary.save_loaded_asset(blend_space)
    # Opening the Blend Space editor runs Unreal's ResampleData (triangulation); save it there.
    unreal.get_editor_subsystem(unreal.AssetEditorSubsystem).open_editor_for_assets([blend_space])
    unreal.log(f"{{ASSET_NAME}}: {{len(SAMPLES)}} samples set; save it in the editor to keep its triangles")


main()
'''


def render(space: EngineSpace) -> tuple[str, list[str]]:
    animations = "\n".join(f"    {s.name!r}: {f'{ANIMATION_FOLDER}/{s.name}'!r}," for s in space.samples)
    axes = "\n".join(
        f"    ({a.label!r}, {_float(a.minimum)}, {_float(a.maximum)}, {a.divisions})," for a in space.axes
    )
    samples = "\n".join(
        f"    ({s.name!r}, {_float(s.position[0])}, {_float(s.position[1])})," for s in space.samples
    )
    text = _TEMPLATE.format(
        name=space.name,
        source=space.source or f"{space.name}.blendspace.json",
        version=__version__,
        file_hint=f"{space.name}{SUFFIX}",
        asset=f"BS_{space.name}",
        animations=animations,
        axes=axes,
        samples=samples,
    )
    return text, _notes(space)


def _float(value: float) -> str:
    """Python float literal: Unreal's float properties get floats, not ints."""
    return repr(rounded(value))


def _notes(space: EngineSpace) -> list[str]:
    notes = [
        f"set SKELETON and the animation asset paths in ANIMATIONS (default {ANIMATION_FOLDER}/<clip>) "
        "before running the script in the Unreal editor",
        "Unreal rebuilds its triangulation itself (Delaunay on min/max-normalised axes, like ours; grid ties "
        "split by its Tangential rule) and only when the asset is opened in the editor: save it there",
    ]
    duplicates = duplicate_positions(space)
    if duplicates:
        pairs = ", ".join(f"{a} = {b}" for a, b in duplicates)
        notes.append(f"Unreal rejects samples at the same position; it will drop one of: {pairs}")
    return notes
