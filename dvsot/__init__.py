"""dvsot: synthesise event-camera (DVS) single-object-tracking datasets and benchmark trackers on them."""

__version__ = "0.1.0"


def __getattr__(name: str):
    """dvsot.simulate_frames (frames -> events -> dataset file), imported on first use: `import dvsot` stays light."""
    if name == "simulate_frames":
        from dvsot.simulation import simulate_frames

        return simulate_frames
    raise AttributeError(f"module 'dvsot' has no attribute {name!r}")
