"""Forensic use of photometric stereo (thesis Chapter 7 and Section 1.4).

- :func:`make_cartridge` -- a procedural fired cartridge case (heights in pixel units for
  rendering, :attr:`Cartridge.height_um` in µm, ``pixel_size``, ground-truth ``regions``);
  sisters share a ``gun`` seed.
- :data:`FINISH_PRESETS`, :func:`acquire` -- brass / nickel appearance and the Chapter 7
  acquisition (16 lights 31x8+62x8, 8-bit, mean intensity ~75/255).
- :func:`estimate_plane`, :func:`tilt_surface`, :func:`reorient`, :func:`level` -- sample
  plane correction (Section 1.4).
- :func:`bandpass`, :func:`register`, :func:`compare` -- band-passed breech-face
  topography, registration over rotation and translation, CCFmax.
- :func:`cmc` -- congruent matching cells (Song 2013; cmcR's defaults): count, cells,
  consensus pose, CCFmax.
- :func:`read_guns`, :func:`match_pixel_size`, :func:`match_topographies` -- folders of real
  X3P scans with their ``guns.csv`` (``$PSBENCH_X3P``), one pixel size per compared pair
  (:mod:`psbench.forensic.scans`).
- :func:`reconstruct_heights` -- psbench's recipe for breech-face heights in µm
  (overexposed images left out, least squares, Poisson); :mod:`.breechface` the real study.
- :func:`evaluate`, :func:`reconstruct`, :func:`score_pairs`, :func:`separation` -- the
  Chapter 7 evaluation as tidy tables (:mod:`psbench.forensic.pipeline`).
"""
from .cartridge import (CASE_DIAMETER, DEFAULT_PIXEL_SIZE, FINISHES, PRIMER_RADIUS, REGIONS,
                        Cartridge, make_cartridge)
from .cmc import CMC_THRESHOLD, CmcResult, Pose, cmc
from .identify import LONG_CUTOFF, SHORT_CUTOFF, Match, bandpass, compare, ncc, register
from .plane import (Plane, estimate_plane, level, level_sample, reorient, rotate_surface,
                    tilt_surface)
from .recipe import MAX_CLIPPED, reconstruct_heights
from .presets import ACQUISITION, FINISH_PRESETS, Acquisition, Finish, acquire
from .scans import match_pixel_size, match_topographies, read_guns

__all__ = ["Cartridge", "make_cartridge", "REGIONS", "FINISHES", "CASE_DIAMETER",
           "PRIMER_RADIUS", "DEFAULT_PIXEL_SIZE", "Finish", "FINISH_PRESETS", "ACQUISITION",
           "Acquisition", "acquire", "Plane", "estimate_plane", "level", "level_sample",
           "tilt_surface", "rotate_surface",
           "reorient", "bandpass", "register", "compare", "ncc", "Match", "SHORT_CUTOFF",
           "LONG_CUTOFF", "cmc", "reconstruct_heights", "MAX_CLIPPED", "CmcResult", "Pose", "CMC_THRESHOLD", "pipeline", "read_guns",
           "match_pixel_size", "match_topographies"]


def __getattr__(name):
    if name == "pipeline":  # imports the solvers; load on first use
        import importlib
        return importlib.import_module(".pipeline", __name__)
    raise AttributeError(f"module 'psbench.forensic' has no attribute {name!r}")
