"""A run's results read: tables (tables), one-pass and per-attribute tables (ope_tables, attribute_tables), the
run's output directory (report), per-sequence result files (sequence_files), pictures (pictures), the energy
table (energy_table) and learning curves (learning_curves)."""
