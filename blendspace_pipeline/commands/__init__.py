"""The `blendspace` sub-commands: one module each, exposing HELP, add_arguments and run."""
