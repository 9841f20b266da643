"""Rules on the beta and style layers (paper §4): axes that do not match, styles that leave part
of the speed range unstyled, masks that name joints the rig does not have."""

from __future__ import annotations

import difflib
from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, LayerView, Rule, SpaceView


class LayerAxes(Rule):
    """A beta layer blends its space with the main one point by point, so both must use the same
    axis features and ranges; otherwise the same (x, y) query means different motions in the two
    spaces and beta blends unrelated clips.
    """

    slug = "layer-axes"
    code = "BS110"
    severity = "error"
    summary = "beta layer on different axes than the main space"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        main = ", ".join(f"{a.feature} [{a.minimum:g}, {a.maximum:g}]" for a in space.axes)
        for layer in space.layers:
            if layer.kind == "beta" and not layer.axes_match:
                theirs = ", ".join(f"{a.feature} [{a.minimum:g}, {a.maximum:g}]" for a in layer.axes)
                yield self.report(
                    f"beta layer {layer.name!r} uses axes {theirs}; the main space uses {main}",
                    hint="give the layer's manifest the same `axes:` as this one",
                )


class StyleCoverage(Rule):
    """A style layer is a 1D space over the main space's speed axis. Where the main space has
    clips (forward or backward) but the style has none on that side, queries there get the
    nearest style clip, e.g. a forward limp played backward. Style clips outside the axis range
    are reported too.
    """

    slug = "style-coverage"
    code = "BS111"
    severity = "warning"
    summary = "style layer missing a side of the axis the main space uses"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for layer in space.layers:
            if layer.kind != "style":
                continue
            axis = layer.axes[0]
            index = next((i for i, a in enumerate(space.axes) if a.feature == axis.feature), 1)
            main = [s.position[index] for s in space.samples]
            styled = [s.position[0] for s in layer.samples]
            for side, word, wanted in ((1.0, "forward", "positive"), (-1.0, "backward", "negative")):
                if any(v * side > 0 for v in main) and not any(v * side > 0 for v in styled):
                    yield self.report(
                        f"style layer {layer.name!r} has no {word} clip ({axis.feature} {wanted}); "
                        f"the main space has {word} clips, which get the nearest style clip instead",
                        hint=f"add a {word} clip to the style (e.g. {layer.name}_{word[:3]})",
                    )
            for sample in layer.samples:
                if not axis.contains(sample.measured[0]):
                    yield self.report(
                        f"style clip {sample.name} measures {axis.feature} {sample.measured[0]:.3g}, "
                        f"outside the axis range [{axis.minimum:g}, {axis.maximum:g}]",
                        hint="widen the axis or check the clip's units",
                    )


class MaskJoints(Rule):
    """A style mask weights joints by name; a name the style's rig does not have is almost always
    a typo (`LeftUpleg` for `LeftUpLeg`) and silently leaves that joint at the default weight.
    """

    slug = "mask-joints"
    code = "BS112"
    severity = "warning"
    summary = "style mask names a joint the rig does not have"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for layer in space.layers:
            if layer.kind != "style" or not layer.mask:
                continue
            joints = _joints(layer)
            if not joints:
                continue
            for name in sorted(layer.mask):
                if name not in joints:
                    close = difflib.get_close_matches(name, sorted(joints), n=1)
                    yield self.report(
                        f"mask of style layer {layer.name!r} names joint {name!r}, "
                        "which its clips do not have",
                        hint=f"did you mean {close[0]!r}?" if close else "check the joint names of the rig",
                    )


def _joints(layer: LayerView) -> set[str]:
    found: set[str] = set()
    for sample in layer.samples:
        found |= set(sample.joint_names)
    return found
