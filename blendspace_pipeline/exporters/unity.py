"""Unity: an Animator Controller (`.controller`, text YAML) whose one state is a 2D blend tree.

The tree is Freeform Cartesian (`m_BlendType: 3`, `BlendTreeType.FreeformCartesian2D`), the
type meant for two unrelated quantities such as turn rate and speed. Unity weights its children
by gradient bands, not by triangles, so weights between samples differ from ours; the positions
are still exactly the snapped ones. Unity has no axis ranges or grid.

Unity references a clip by the GUID in its asset's `.meta` and the clip's local file ID. With
``--unity-project`` the export reads them (`unity_clips`) and each child gets its real motion; a
re-export keeps every motion the previous controller had at the same position (hand
assignments survive). Generated clips get a `.meta` beside their GLB with a GUID derived from
the clip's name, so the GUID is the same on every build and re-export.
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

from blendspace_pipeline.exporters import (
    Convention,
    EngineSample,
    EngineSpace,
    ExportContext,
    format_number,
    rounded,
)

# Left-handed, Y up, metres, degrees: positive yaw (Transform.eulerAngles.y) turns right
# (clockwise seen from above) and +x is the character's right, so handed features flip sign.
CONVENTION = Convention(
    engine="Unity",
    length_unit="m",
    metres_to_length=1.0,
    angle_unit="deg",
    degrees_to_angle=1.0,
    left_positive=False,
    handedness="left-handed, Y up, metres, degrees",
)
SUFFIX = ".controller"
REPLACES = (
    "a Unity animator controller"  # what an existing --out may be (`replaceable`); anything else is refused
)


def replaceable(text: str) -> bool:
    """Whether an existing --out file is this engine's file of a blend space, one a re-export
    may replace (keeping what the engine added to it); any other file is the user's."""
    return text.lstrip("\ufeff").startswith("%YAML") and "AnimatorController:" in text


LAYER_ADVICE = (
    "add them as Animator layers: a beta space as a second 2D blend tree mixed in a parent Simple 1D tree, "
    "a style as an override layer with an Avatar Mask for its joints"
)
FREEFORM_CARTESIAN_2D = 3  # UnityEditor.Animations.BlendTreeType
FLOAT_PARAMETER = 1  # AnimatorControllerParameterType.Float

# Local file IDs inside the controller; 9100000 is Unity's fixed ID for the controller itself.
CONTROLLER_ID = 9100000
STATE_MACHINE_ID = 1107100000000000000
STATE_ID = 1102100000000000000
BLEND_TREE_ID = 206100000000000000


ANIMATION_CLIP_FILE_ID = 7400000  # an `.anim` asset's clip: class 74, the asset's main object
_ASSET_REFERENCE = 2  # `type:` of a reference to a native asset (.anim)
_IMPORTED_REFERENCE = 3  # `type:` of a reference to an object an importer made (FBX, GLB)
# Unity's BlendTreeInspector.ValidatePositions: two children closer than 1 % of its blend rect's
# height are "too close"; for a Freeform Cartesian tree that rect is 1.35 x the larger of the two
# position spans (Get2DBlendRect), whatever the units of either axis.
_UNITY_TOO_CLOSE = 0.01
_UNITY_RECT_PADDING = 1.35


@dataclass(frozen=True)
class Motion:
    """A reference to an animation clip in a Unity project."""

    file_id: int
    guid: str
    type: int

    def text(self) -> str:
        return f"{{fileID: {self.file_id}, guid: {self.guid}, type: {self.type}}}"


def render(space: EngineSpace, context: ExportContext) -> tuple[str, list[str], dict[Path, str]]:
    project = unity_clips(context.unity_project) if context.unity_project is not None else {}
    kept = previous_motions(context.previous)
    metas = _generated_metas(space, context)
    motions: list[str] = []
    unassigned: list[str] = []
    for sample in space.samples:
        motion = kept.get(_key(sample.position)) or _found(sample, project)
        if motion is None:
            unassigned.append(sample.name)
        motions.append(motion or "{fileID: 0}")
    # In ascending file ID, the order Unity saves objects in, so its first save changes no lines.
    parts = [
        "%YAML 1.1\n%TAG !u! tag:unity3d.com,2011:\n",
        _controller(space),
        _blend_tree(space, motions),
        _state(space),
        _state_machine(),
    ]
    extra = {path: text for path, (text, exists) in metas.items() if not exists}
    return "".join(parts), _notes(space, unassigned, context), extra


def unity_clips(project: Path) -> dict[str, Motion]:
    """Clip name (and asset file stem) -> motion, from every `.meta` under the project's Assets.

    An `.anim` is one clip, the asset's main object. A model (FBX, and anything another importer
    lists the same way) names its clips in ``internalIDToNameTable`` (class 74 entries) or, in
    metas older than Unity 2019.3, ``fileIDToRecycleName``; a model holding a single clip is also
    found by its file name, since exporters often call the take "Take 001" or "mixamo.com".
    """
    root = project / "Assets" if (project / "Assets").is_dir() else project
    found: dict[str, Motion] = {}
    for meta in sorted(root.rglob("*.meta")):
        text = meta.read_text(encoding="utf-8", errors="replace")
        guid = re.search(r"^guid:\s*([0-9a-f]{32})\s*$", text, re.MULTILINE)
        if guid is None:
            continue
        asset = meta.with_suffix("")
        stem = asset.name.split(".")[0]
        if asset.suffix.lower() == ".anim":
            found.setdefault(stem, Motion(ANIMATION_CLIP_FILE_ID, guid.group(1), _ASSET_REFERENCE))
            continue
        clips = re.findall(r"-\s*first:\s*\n\s*74:\s*(-?\d+)\s*\n\s*second:\s*(.+?)\s*$", text, re.MULTILINE)
        clips += [
            (file_id, name) for file_id, name in re.findall(r"^\s+(74\d{5}):\s*(.+?)\s*$", text, re.MULTILINE)
        ]
        for file_id, name in clips:
            found.setdefault(name.strip("'\""), Motion(int(file_id), guid.group(1), _IMPORTED_REFERENCE))
        if len({file_id for file_id, _ in clips}) == 1:
            found.setdefault(stem, Motion(int(clips[0][0]), guid.group(1), _IMPORTED_REFERENCE))
    return found


def previous_motions(text: str | None) -> dict[tuple[float, float], str]:
    """Position -> assigned motion in the controller being replaced (unassigned children skipped)."""
    kept: dict[tuple[float, float], str] = {}
    pattern = r"m_Motion: (\{[^}]*\})\n(?:\s+\w+: [^\n]*\n)*?\s+m_Position: \{x: ([^,]+), y: ([^}]+)\}"
    for motion, x, y in re.findall(pattern, text or ""):
        if "guid:" in motion:
            kept[_key((float(x), float(y)))] = motion
    return kept


def stable_guid(name: str) -> str:
    """A Unity GUID (32 hex digits) that is the same on every build of the clip ``name``."""
    return hashlib.md5(f"blendspace-pipeline/clip/{name}".encode()).hexdigest()


def too_close_pairs(positions: list[tuple[str, tuple[float, float]]]) -> list[tuple[str, str]]:
    """The pairs Unity's inspector flags "Two or more of the positions are too close to each other"."""
    if not positions:
        return []
    xs = [p[0] for _, p in positions]
    ys = [p[1] for _, p in positions]
    height = _UNITY_RECT_PADDING * max(max(xs) - min(xs), max(ys) - min(ys))
    if height == 0:
        height = 2 * _UNITY_RECT_PADDING  # Get2DBlendRect's half-size 1 when every point coincides
    pairs = []
    for i, (name_i, a) in enumerate(positions):
        for name_j, b in positions[:i]:
            if ((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) / height**2 < _UNITY_TOO_CLOSE**2:
                pairs.append((name_j, name_i))
    return pairs


def _key(position: tuple[float, float]) -> tuple[float, float]:
    return (round(rounded(position[0]), 6) + 0.0, round(rounded(position[1]), 6) + 0.0)


def _found(sample: EngineSample, project: dict[str, Motion]) -> str | None:
    for name in (sample.name, Path(sample.source).stem):
        if name in project:
            return project[name].text()
    return None


def _generated_metas(space: EngineSpace, context: ExportContext) -> dict[Path, tuple[str, bool]]:
    """`.meta` text for each generated clip's GLB, and whether one is already there (kept as is)."""
    metas: dict[Path, tuple[str, bool]] = {}
    for sample in space.samples:
        if not sample.generated:
            continue
        for clip in context.clip_files.get(sample.name, []):
            if clip.suffix.lower() != ".glb":
                continue
            meta = clip.with_name(clip.name + ".meta")
            text = f"fileFormatVersion: 2\nguid: {stable_guid(sample.name)}\n"
            metas[meta] = (text, meta.exists())
    return metas


def _header(class_id: int, file_id: int, type_name: str, hide_flags: int, version: int | None = None) -> str:
    """A document's tag line and the fields every Unity object starts with."""
    serialized = f"  serializedVersion: {version}\n" if version is not None else ""
    return (
        f"--- !u!{class_id} &{file_id}\n{type_name}:\n{serialized}  m_ObjectHideFlags: {hide_flags}\n"
        "  m_CorrespondingSourceObject: {fileID: 0}\n  m_PrefabInstance: {fileID: 0}\n"
        "  m_PrefabAsset: {fileID: 0}\n"
    )


def _parameter(name: str) -> str:
    return (
        f"  - m_Name: {_scalar(name)}\n    m_Type: {FLOAT_PARAMETER}\n    m_DefaultFloat: 0\n"
        f"    m_DefaultInt: 0\n    m_DefaultBool: 0\n    m_Controller: {{fileID: {CONTROLLER_ID}}}\n"
    )


def _controller(space: EngineSpace) -> str:
    parameters = "".join(_parameter(axis.feature) for axis in space.axes)
    return (
        _header(91, CONTROLLER_ID, "AnimatorController", 0)
        + f"  m_Name: {_scalar(space.name)}\n  serializedVersion: 5\n  m_AnimatorParameters:\n{parameters}"
        "  m_AnimatorLayers:\n  - serializedVersion: 5\n    m_Name: Base Layer\n"
        f"    m_StateMachine: {{fileID: {STATE_MACHINE_ID}}}\n    m_Mask: {{fileID: 0}}\n"
        "    m_Motions: []\n    m_Behaviours: []\n    m_BlendingMode: 0\n    m_SyncedLayerIndex: -1\n"
        "    m_DefaultWeight: 0\n    m_IKPass: 0\n    m_SyncedLayerAffectsTiming: 0\n"
        f"    m_Controller: {{fileID: {CONTROLLER_ID}}}\n"
    )


def _state_machine() -> str:
    return (
        _header(1107, STATE_MACHINE_ID, "AnimatorStateMachine", 1, version=6)
        + "  m_Name: Base Layer\n  m_ChildStates:\n  - serializedVersion: 1\n"
        f"    m_State: {{fileID: {STATE_ID}}}\n    m_Position: {{x: 300, y: 120, z: 0}}\n"
        "  m_ChildStateMachines: []\n  m_AnyStateTransitions: []\n  m_EntryTransitions: []\n"
        "  m_StateMachineTransitions: {}\n  m_StateMachineBehaviours: []\n"
        "  m_AnyStatePosition: {x: 50, y: 20, z: 0}\n  m_EntryPosition: {x: 50, y: 120, z: 0}\n"
        "  m_ExitPosition: {x: 800, y: 120, z: 0}\n  m_ParentStateMachinePosition: {x: 800, y: 20, z: 0}\n"
        f"  m_DefaultState: {{fileID: {STATE_ID}}}\n"
    )


def _state(space: EngineSpace) -> str:
    return (
        _header(1102, STATE_ID, "AnimatorState", 1, version=6)
        + f"  m_Name: {_scalar(space.name)}\n  m_Speed: 1\n  m_CycleOffset: 0\n  m_Transitions: []\n"
        "  m_StateMachineBehaviours: []\n  m_Position: {x: 50, y: 50, z: 0}\n  m_IKOnFeet: 0\n"
        "  m_WriteDefaultValues: 1\n  m_Mirror: 0\n  m_SpeedParameterActive: 0\n"
        "  m_MirrorParameterActive: 0\n  m_CycleOffsetParameterActive: 0\n  m_TimeParameterActive: 0\n"
        f"  m_Motion: {{fileID: {BLEND_TREE_ID}}}\n  m_Tag: \n  m_SpeedParameter: \n"
        "  m_MirrorParameter: \n  m_CycleOffsetParameter: \n  m_TimeParameter: \n"
    )


def _child(position: tuple[float, float], x_parameter: str, motion: str) -> str:
    return (
        f"  - serializedVersion: 2\n    m_Motion: {motion}\n    m_Threshold: 0\n"
        f"    m_Position: {{x: {format_number(position[0])}, y: {format_number(position[1])}}}\n"
        f"    m_TimeScale: 1\n    m_CycleOffset: 0\n    m_DirectBlendParameter: {_scalar(x_parameter)}\n"
        "    m_Mirror: 0\n"
    )


def _blend_tree(space: EngineSpace, motions: list[str]) -> str:
    x_axis, y_axis = space.axes
    children = "".join(
        _child(sample.position, x_axis.feature, motion)
        for sample, motion in zip(space.samples, motions, strict=True)
    )
    return (
        _header(206, BLEND_TREE_ID, "BlendTree", 1)
        + f"  m_Name: {_scalar(space.name)}\n  m_Childs:\n{children}"
        f"  m_BlendParameter: {_scalar(x_axis.feature)}\n  m_BlendParameterY: {_scalar(y_axis.feature)}\n"
        "  m_MinThreshold: 0\n  m_MaxThreshold: 1\n  m_UseAutomaticThresholds: 0\n"
        f"  m_NormalizedBlendValues: 0\n  m_BlendType: {FREEFORM_CARTESIAN_2D}\n"
    )


def _scalar(text: str) -> str:
    """A YAML plain scalar when safe, else a double-quoted one (Unity reads both)."""
    plain = (
        text and all(c.isalnum() or c in "_-. " for c in text) and text[0] not in "-. " and text[-1] != " "
    )
    if plain:
        return text
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _notes(space: EngineSpace, unassigned: list[str], context: ExportContext) -> list[str]:
    notes = [
        "Unity weights a Freeform Cartesian tree by gradient bands, not by our triangles: positions match, "
        "weights between samples differ from `blendspace eval` (and the triangle rules do not apply)",
        "Unity has no axis ranges or grid: parameters are unbounded and nothing snaps; the positions are the "
        "snapped ones",
    ]
    if unassigned:
        order = ", ".join(
            f"{index}: {sample.name}"
            for index, sample in enumerate(space.samples)
            if sample.name in unassigned
        )
        where = (
            "found no clip of that name in the project's .meta files"
            if context.unity_project is not None
            else "pass --unity-project to read their GUIDs from the project's .meta files"
        )
        notes.append(f"Motions not assigned ({where}): assign them in the Inspector: {order}")
    pairs = too_close_pairs([(s.name, s.position) for s in space.samples])
    if pairs:
        listing = ", ".join(f"{a} / {b}" for a, b in pairs)
        notes.append(
            'Unity\'s inspector will warn "Two or more of the positions are too close to each other" (it '
            f"measures 1 % of the larger axis span, mixing units): {listing}"
        )
    return notes
