"""Benchmark suite: trackers behind one interface, the A/R/ARscore protocol, tables, performance scripts."""
