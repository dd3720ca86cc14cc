"""The run directory: its file layout, written by the sweep and read by reduce, report and export."""
