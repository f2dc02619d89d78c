"""Defaults shared by the library and the command line, in a module that imports nothing (`dvsot --help` stays light)."""

SEGMENT_US = 10_000  # segment length (microseconds): the paper's 10 ms segments
