"""A run's results read: tables (tables), the run's output directory (report), per-sequence result files
(sequence_files), pictures (pictures) and the energy table (energy_table)."""
