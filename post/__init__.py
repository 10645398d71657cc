"""Stage 3 of the toolkit: reads the VTK frames of an output folder (docs/FORMATS.md), measures
phi, Z, the granular stress, P and K, fits the paper's laws and plots.

Modules: frames (reading), measures (pure measures on arrays), table (one row per frame),
models (the paper's laws), fits, plots (matplotlib), render (optional pyvista).
Command line: ``python -m post OUT_DIR [--friction MU | --min-contacts K]``.
"""

from post.errors import OutputError
from post.frames import Frame, iter_frames, read_frame, read_frames_table
from post.table import COLUMNS, measure_frame, measure_output, read_measures, write_measures

__all__ = ["COLUMNS", "Frame", "OutputError", "iter_frames", "measure_frame", "measure_output", "read_frame",
           "read_frames_table", "read_measures", "write_measures"]
