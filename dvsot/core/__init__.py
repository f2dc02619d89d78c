"""The basics every stage uses: exceptions (errors), shared defaults (defaults), strict schema types (strict),
YAML 1.2 (yaml12), public names imported on first use (lazy), and bounds on input with their checks (bounds).

It imports nothing heavy, so that `import dvsot` and `dvsot --help` stay light.
"""
