"""Events: the ESIM-style simulator (simulator), its compiled kernel (kernel), the sensor model's stages (sensor)
and presets (presets), the event batch (batch), object labels per event (labels) and the frame sources
`dvsot simulate` reads (frame_sources); the names callers use, each imported on first use."""

from dvsot.core.lazy import lazy_attributes

_API = {
    "EventSimulator": "dvsot.events.simulator",
    "EventParams": "dvsot.events.simulator",
    "CodedFrame": "dvsot.events.simulator",
    "log_intensity": "dvsot.events.simulator",
    "EventBatch": "dvsot.events.batch",
    "STRUCTURED_DTYPE": "dvsot.events.batch",
}
__all__ = list(_API)
__getattr__, __dir__ = lazy_attributes(__name__, _API)
