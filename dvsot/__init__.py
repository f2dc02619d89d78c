"""dvsot: synthesise event-camera (DVS) single-object-tracking datasets and benchmark trackers on them."""

__version__ = "0.1.0"
