"""detection-guess: an up axis, unit, root or facing the clip's data did not settle."""

from __future__ import annotations

from collections.abc import Iterator

from blendspace_pipeline.api import Diagnostic, Rule, SpaceView


class DetectionGuess(Rule):
    """BVH states no unit and no up axis, and some rigs have no recognisable hips. The build
    reads these from the body (the feet-hips-head direction for up, the leg's length against
    human legs in m, cm, mm, inches or CMU units) and, when that evidence is weak, has to guess.
    A wrong guess silently scales every speed or turns forward into sideways, so every guess is
    reported with the evidence and the exact manifest setting that replaces it (at the top-level
    `skeleton:` or on the clip's own entry).
    """

    slug = "detection-guess"
    code = "BS006"
    severity = "warning"
    summary = "up axis, unit, root or facing guessed with low confidence"

    def check(self, space: SpaceView) -> Iterator[Diagnostic]:
        for sample in space.samples:
            if sample.generated:
                continue
            for guess in sample.guesses:
                if guess.stated and not guess.override.startswith("skeleton:"):
                    # Nothing in the manifest can right it (root motion in another unit than the
                    # bones, an axis no manifest states): the file must change.
                    message = f"{guess.what} {guess.value[:-1]}, doubted: {guess.evidence})"
                    hint = f"{guess.override}; if it is right, add `ignore: [{{rule: detection-guess, reason: ...}}]`"
                elif guess.stated:  # a value the file or the manifest states: used, and doubted aloud
                    message = f"{guess.what} {guess.value[:-1]}, doubted: {guess.evidence})"
                    hint = (
                        f"if that reading is right, set `{guess.override}` on the clip's entry (or the "
                        "top-level `skeleton:`); if the stated value is, state it in the manifest (a file's "
                        "unit repeated there is settled) or add `ignore: [{rule: detection-guess, reason: ...}]`"
                    )
                else:
                    message = f"{guess.what} guessed as {guess.value} ({guess.evidence})"
                    hint = (
                        f"`{guess.override}` on the clip's entry (or the top-level `skeleton:`) confirms the "
                        "guess; give the right value there if it is wrong (units: m, cm, mm, in or metres per "
                        "unit; up: y or z)"
                    )
                yield self.report(
                    f"{sample.name}: {message}", clips=[sample.name], position=sample.position, hint=hint
                )
