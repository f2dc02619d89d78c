"""dvsot: synthesise event-camera (DVS) single-object-tracking datasets and benchmark trackers on them.

The Python API (README, "Use it from Python"): `load_scene` -> `generate` renders a scene into a dataset
file, `generate_scenes` scene files into one each (`dvsot generate`), `generate_variants` draws scene variants
from a template and renders them (`read_template` -> `draw_variants` draws them only; `generate_many` renders tasks
from `variant_tasks`, `scene_tasks` or `many_tasks`); `simulate_file` turns frames you have (images, video, .npy)
into one, `EventSimulator` + `write_sequence` / `simulate_frames` any frames you make; `Dataset` reads it,
`dataset_info` sums it up, `SegmentDataset` feeds PyTorch; `export_dataset` writes other tools' event files and
`import_recording` reads them (with a recording's boxes). Each name is imported on first use, so `import dvsot` stays
light (no torch, no bpy).
"""

from dvsot.core.lazy import lazy_attributes

__version__ = "0.1.0"

_API = {
    "load_scene": "dvsot.scene",
    "SceneConfig": "dvsot.scene",
    "generate": "dvsot.pipeline.generate",
    "generate_scenes": "dvsot.pipeline.many_scenes",
    "generate_variants": "dvsot.pipeline.many_scenes",
    "generate_many": "dvsot.pipeline.many_scenes",
    "many_tasks": "dvsot.pipeline.scene_sources",
    "variant_tasks": "dvsot.pipeline.scene_sources",
    "scene_tasks": "dvsot.pipeline.scene_sources",
    "read_template": "dvsot.scene.templates",
    "draw_variants": "dvsot.scene.templates",
    "simulate_frames": "dvsot.pipeline.sequence",
    "write_sequence": "dvsot.pipeline.sequence",
    "simulate_file": "dvsot.pipeline.simulate",
    "EventSimulator": "dvsot.events",
    "EventParams": "dvsot.events",
    "EventBatch": "dvsot.events",
    "Dataset": "dvsot.dataset",
    "DatasetWriter": "dvsot.dataset",
    "find_datasets": "dvsot.dataset",
    "dataset_info": "dvsot.dataset.info",
    "SegmentDataset": "dvsot.dataset.torchdata",
    "export_dataset": "dvsot.interop.event_files",
    "read_event_file": "dvsot.interop.event_files",
    "import_recording": "dvsot.interop.recordings",
    "UserError": "dvsot.core.errors",
    "RunError": "dvsot.core.errors",
}
__all__ = ["__version__", *_API]
__getattr__, __dir__ = lazy_attributes(__name__, _API)
