"""inconsistent-fps and inconsistent-skeleton: clips that do not belong in one blend."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator

from blendspace_pipeline.rules._agreement import close, most_agreed

from blendspace_pipeline.api import Diagnostic, Rule, SampleView, SpaceView

# Rates within 2 % are one export: a reader that fits whole frames to an animation's length
# samples 30 fps keys at 30.4 fps (the Godot TPS demo's walk), 24 at 24.17 (a glTF clip); the mixed
# exports this rule is for differ by 4 % (24 and 25 fps) or more.
SAME_RATE = 0.02


class InconsistentFps(Rule):
    """Clips sampled at different rates blend fine in engines but usually reveal a mixed export
    (a 30 fps clip among 120 fps mocap); generated clips and cadence sync assume one rate. A
    layer's clips are compared with the main set's rate. A still pose has no rate to disagree
    with: a glTF idle keyed on its first and last frames tells none (its two keys fit 24 fps as
    well as the set's 30).
    """

    slug = "inconsistent-fps"
    code = "BS107"
    severity = "info"
    summary = "clips with different frame rates"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        moving = [s for s in space.samples if not s.generated and not s.holds_still]
        rates = Counter(round(s.fps, 3) for s in moving if s.fps > 0)
        if not rates:
            return
        common = most_agreed(rates, float, SAME_RATE)
        odd = [s.name for s in moving if not close(s.fps, common, SAME_RATE)]
        if odd:
            yield self.report(
                f"most clips run at {common:g} fps but {', '.join(odd)} do not",
                clips=odd,
                hint="re-export at one frame rate",
            )
        # A layer's clips are blended pose for pose with the main space's, at its rate.
        for layer in space.layers:
            off = [
                s
                for s in layer.samples
                if not close(s.fps, common, SAME_RATE) and not s.generated and not s.holds_still
            ]
            if off:
                yield self.report(
                    f"{layer.kind} layer {layer.name!r}: {', '.join(f'{s.name} ({s.fps:g} fps)' for s in off)} "
                    f"blend with main clips that run at {common:g} fps",
                    clips=[s.name for s in off],
                    hint="re-export the layer's clips at the main space's frame rate",
                )


class InconsistentSkeleton(Rule):
    """Blending needs one skeleton: the same joints, under the same parents, in the same order. A
    clip on another skeleton cannot be blended with the rest, mirrored against it, or interpolated
    (its blends are left out of the foot-skate map). A style or beta layer's clips are blended
    joint by joint with the main space's, so they are held to the main set's skeleton too. A clip
    without a hierarchy (a Godot track set) is compared by its joint names.
    """

    slug = "inconsistent-skeleton"
    code = "BS108"
    severity = "warning"
    summary = "clips whose joints differ from the rest of the set"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        named = [s for s in space.samples if s.joint_names]
        if not named:
            return
        names = Counter(s.joint_names for s in named).most_common(1)[0][0]
        # The set's hierarchy: the most common one among the clips of its joint names that have one.
        hierarchies = Counter(s.joint_parents for s in named if s.joint_names == names and _has_parents(s))
        common = (names, hierarchies.most_common(1)[0][0] if hierarchies else None)
        for sample in named:
            if _differs(sample, common):
                yield self.report(
                    f"{sample.name} has a different skeleton ({_difference(sample, common)})",
                    clips=[sample.name],
                    position=sample.position,
                    hint="retarget the clip onto the set's skeleton before blending",
                )
        # A style or beta layer's poses are blended joint by joint with the main space's.
        for layer in space.layers:
            for sample in layer.samples:
                if sample.joint_names and _differs(sample, common):
                    yield self.report(
                        f"{layer.kind} layer {layer.name!r}: {sample.name} has another skeleton than the "
                        f"main space's clips ({_difference(sample, common)})",
                        clips=[sample.name],
                        hint="retarget the layer's clip onto the main space's skeleton",
                    )


# (joint names, parent indices or None where no clip of those names has a hierarchy).
Layout = tuple[tuple[str, ...], tuple[int, ...] | None]


def _has_parents(sample: SampleView) -> bool:
    return len(sample.joint_parents) == len(sample.joint_names)


def _differs(sample: SampleView, common: Layout) -> bool:
    """Other joints, or (both with a hierarchy) other parents; same names mean parent indices
    compare as parent names do."""
    names, parents = common
    if sample.joint_names != names:
        return True
    return parents is not None and _has_parents(sample) and sample.joint_parents != parents


def _parent_names(names: tuple[str, ...], parents: tuple[int, ...]) -> dict[str, str]:
    return {name: names[p] if 0 <= p < len(names) else "" for name, p in zip(names, parents, strict=True)}


def _difference(sample: SampleView, common: Layout) -> str:
    """What differs, in the order a TD fixes it: the joints, then where they hang, then their order."""
    joints, usual = sample.joint_names, common[0]
    missing = sorted(set(usual) - set(joints))[:5]
    extra = sorted(set(joints) - set(usual))[:5]
    here = _parent_names(joints, sample.joint_parents) if _has_parents(sample) else None
    there = _parent_names(usual, common[1]) if common[1] is not None else None
    roots = [_root(here), _root(there)]
    if roots[0] in extra and roots[1] in missing and len(missing) == len(extra) == 1:
        # Blender names an FBX's armature node after the armature object (after the file, for an
        # imported BVH): engines bind by it (Unity's Generic curve paths, Unreal's root bone).
        return (
            f"its root joint is named {roots[0]!r}, the set's {roots[1]!r}; engines bind clips "
            "by it, and a DCC's export often names it after the armature object: give every clip the same one"
        )
    if missing or extra or len(joints) != len(usual):
        return f"{len(joints)} joints vs {len(usual)}; missing {missing or '-'}, extra {extra or '-'}"
    if here is not None and there is not None:
        moved = [name for name in usual if here[name] != there[name]]
        if moved:
            shown = "; ".join(
                f"{name} under {here[name] or 'no parent'}, not {there[name] or 'no parent'} as in the set"
                for name in moved[:3]
            )
            more = f" and {len(moved) - 3} more" if len(moved) > 3 else ""
            return f"the same {len(joints)} joints in another hierarchy: {shown}{more}"
    first = next(i for i, (a, b) in enumerate(zip(joints, usual, strict=True)) if a != b)
    return (
        f"the same {len(joints)} joints and hierarchy in another order from joint {first + 1}, "
        f"{joints[first]} where the set has {usual[first]}: re-export in the set's joint order"
    )


def _root(parents: dict[str, str] | None) -> str | None:
    """The first joint without a parent, when the hierarchy is known."""
    if parents is None:
        return None
    return next((name for name, parent in parents.items() if parent == ""), None)
