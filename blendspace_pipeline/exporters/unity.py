"""Unity: an Animator Controller (`.controller`, text YAML) whose one state is a 2D blend tree.

The tree is Freeform Cartesian (`m_BlendType: 3`, `BlendTreeType.FreeformCartesian2D`), the
type meant for two unrelated quantities such as turn rate and speed. Unity weights its children
by gradient bands, not by triangles, so weights between samples differ from ours; the positions
are still exactly the snapped ones. Unity has no axis ranges or grid, and it references clips by
GUID, which we cannot know: the children are written in sample order with no motion assigned.
"""

from __future__ import annotations

from blendspace_pipeline.exporters import Convention, EngineSpace, format_number

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


def render(space: EngineSpace) -> tuple[str, list[str]]:
    parts = [
        "%YAML 1.1\n%TAG !u! tag:unity3d.com,2011:\n",
        _controller(space),
        _state_machine(),
        _state(space),
        _blend_tree(space),
    ]
    return "".join(parts), _notes(space)


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


def _child(position: tuple[float, float], x_parameter: str) -> str:
    return (
        "  - serializedVersion: 2\n    m_Motion: {fileID: 0}\n    m_Threshold: 0\n"
        f"    m_Position: {{x: {format_number(position[0])}, y: {format_number(position[1])}}}\n"
        f"    m_TimeScale: 1\n    m_CycleOffset: 0\n    m_DirectBlendParameter: {_scalar(x_parameter)}\n"
        "    m_Mirror: 0\n"
    )


def _blend_tree(space: EngineSpace) -> str:
    x_axis, y_axis = space.axes
    children = "".join(_child(sample.position, x_axis.feature) for sample in space.samples)
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


def _notes(space: EngineSpace) -> list[str]:
    order = ", ".join(f"{index}: {sample.name}" for index, sample in enumerate(space.samples))
    return [
        "Unity weights a Freeform Cartesian tree by gradient bands, not by our triangles: positions match, "
        "weights between samples differ from `blendspace eval` (and the triangle rules do not apply)",
        "Unity has no axis ranges or grid: parameters are unbounded and nothing snaps; the positions are the "
        "snapped ones",
        f"Unity references clips by GUID: assign each child's Motion in the Inspector, in order: {order}",
    ]
