"""blendspace-pipeline: measure locomotion clips, place them in a blend space, check and fix it."""

__version__ = "0.1.0"
