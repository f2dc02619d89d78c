"""Other tools' files: event files in and out (event_files: AEDAT4, EVT2/3, DAT; text_events: CSV, TXT), checked
text inputs (text_inputs: timestamps, box CSVs) and recordings with annotated boxes (recordings)."""
