"""SCTN: the spiking convolutional tracking network (C-LIF neurons, STCA-style training, tracking, energy).

Public names (each imported on first use): the model `SCTN` and its `NetworkConfig`, the tracker
`SCTNTracker` and its `SCTNParams`, training (`train`: SCTN as an SNN, `train_twin`: its ANN twin,
`TrainConfig`, `finetune`) and checkpoints (`load_checkpoint`, `save_checkpoint`), and NIR export
(`export_nir`, `sctn_graph`: docs/nir.md).
"""

from dvsot.core.lazy import lazy_attributes

_API = {
    "SCTN": "sctn.network",
    "NetworkConfig": "sctn.network",
    "SCTNTracker": "sctn.tracker",
    "SCTNParams": "sctn.params",
    "train": "sctn.training.snn",
    "train_twin": "sctn.ann",
    "TrainConfig": "sctn.training.snn",
    "finetune": "sctn.finetune",
    "load_checkpoint": "sctn.checkpoint",
    "save_checkpoint": "sctn.checkpoint",
    "export_nir": "sctn.nir_export",
    "sctn_graph": "sctn.nir_export",
}
__all__ = list(_API)
__getattr__, __dir__ = lazy_attributes(__name__, _API)
