"""Defaults shared by the library and the command line, in a module that imports nothing (`dvsot --help` stays
light)."""

SEGMENT_US = 10_000  # segment length (microseconds): the paper's 10 ms segments
# .raw written by dvsot export: EVT 2, which faery and expelliarmus (tonic's reader) decode exactly;
# expelliarmus 1.1 adds 4096 us to EVT 3 times at every time-high step (docs/dataset-files.md)
EXPORT_EVT_VERSION = "evt2"
# .raw read whose header names no version: EVT 3, what Prophesee's Gen 4 / IMX636 cameras record
IMPORT_EVT_VERSION = "evt3"
