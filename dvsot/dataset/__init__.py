"""The dvsot dataset file (HDF5): its format (dvsot.dataset.format), the streaming writer, the checked lazy
reader and its validation; the names callers use are re-exported here."""

from dvsot.dataset.format import COMPRESSIONS, FORMAT, FORMAT_VERSION, BoxTrack, ObjectTrack, Segment
from dvsot.dataset.reader import Dataset, find_datasets, open_dataset
from dvsot.dataset.writer import DatasetWriter

__all__ = ["COMPRESSIONS", "FORMAT", "FORMAT_VERSION", "BoxTrack", "Dataset", "DatasetWriter", "ObjectTrack",
           "Segment", "find_datasets", "open_dataset"]
