"""Error measures of thesis Section 2.6: NE, IE (module :mod:`~psbench.metrics.errors`)
and the quality factor QF of a mask (:mod:`~psbench.metrics.quality`)."""
from .errors import (NORMS, dynamic_range, ie_relative, intensity_error, intensity_error_map,
                     ne_by_zenith, normal_error, normal_error_map, normal_error_stats,
                     weighted_intensity_error)
from .quality import quality_counts, quality_factor

__all__ = ["normal_error_map", "normal_error", "normal_error_stats", "ne_by_zenith",
           "intensity_error", "intensity_error_map", "weighted_intensity_error", "ie_relative",
           "dynamic_range", "quality_factor", "quality_counts", "NORMS"]
