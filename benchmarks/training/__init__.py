"""Training every model through one registry: the registry (registry) and a whole run to a checkpoint (run)."""
