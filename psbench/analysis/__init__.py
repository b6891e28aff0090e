"""Chapter 4 / Section 5.7 analyses as tidy pandas DataFrames (no plotting, no file I/O).

psbench's own analyses are in :mod:`~psbench.analysis.builtin`; ``_common`` holds what
they share (scenes, solves, bins).
"""
from .._shared.deprecation import renamed_names
from .builtin import (IMAGE_KINDS, TRUTHS, breechface, diffuse_counts, forensic,
                      highlight_truth_options,
                      ie_decomposition, mask_scores, ne_vs_image_count, ne_vs_source_zenith,
                      ne_vs_surface_zenith, propose_zeniths, table_5_5, table_5_6, wps_table)

__all__ = ["ne_vs_surface_zenith", "ie_decomposition", "ne_vs_image_count",
           "ne_vs_source_zenith", "propose_zeniths", "wps_table", "table_5_5", "table_5_6",
           "mask_scores", "highlight_truth_options", "diffuse_counts", "forensic", "breechface",
           "IMAGE_KINDS", "TRUTHS"]

__getattr__ = renamed_names(globals(), {"KINDS": "IMAGE_KINDS"})
