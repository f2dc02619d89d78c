"""Sub-commands of the `dvsot` command line; each module has `add_arguments(parser)` and `run(args) -> int`.

Heavy imports (bpy, torch) stay inside `run` so that `dvsot --help` is fast and a machine without
Blender can still run `dvsot bench`.
"""
