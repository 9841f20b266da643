"""The built-in rules of blendspace-pipeline, installed as `blendspace_pipeline.rules`.

Each module here is written exactly like a studio's rule module (see CONTRIBUTING.md): it
imports only `blendspace_pipeline.api` and defines `Rule` subclasses. The engine loads these
through the same loader as plugins.
"""
