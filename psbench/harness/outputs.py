"""Pictures of ``psbench`` runs: where they go and writing them.

Every run of the ``psbench`` command (not the runs of an experiment grid) writes its
outputs to a folder of its own, built under a temporary name and renamed into place:

- a single run: ``out=DIR`` when given, else ``<results_dir>/out/<sweep>/<run_id>/``;
- each job of a ``-m`` sweep: ``<DIR>/<run_id>/`` with ``DIR`` = ``out`` or
  ``<results_dir>/out/<sweep>/``; the sweep's summary and comparison sheet
  (:mod:`psbench.harness.sweep`, :mod:`psbench.harness.sheet`) go to ``DIR``.

What is written is set by ``outputs=``: ``pictures`` (default: the PNGs of
:func:`psbench.io.write_outputs`: input, normals, ground truth, NE map with colour bar,
albedo, mask overlay, weights and the shaded heights, which cost a small part of a run),
``all`` (pictures, the compressed ``.npz`` arrays and the height meshes ``mesh.ply`` / ``mesh.obj``,
which cost more time than the pictures and ~35 MB at 512 x 512, so they are written when asked
for), ``none``. A run whose pixel size is known (a cartridge case, an ``.x3p`` surface, a
capture whose calibration measured it) also writes its heights as ``height.x3p`` in µm. ``run.json`` in the folder describes the run (its printed row, parameters
and figures); the comparison sheet reads it.
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError

__all__ = ["LEVELS", "MARKER", "level", "run_dir", "sweep_dir", "check_dir", "present",
           "write_run", "copy_stored", "read_run_info"]

LEVELS = ("pictures", "all", "none")
#: the file that marks a folder as a psbench run's outputs
MARKER = "run.json"
_FIGURES = ("ne_mean", "ne_median", "ie_l2", "ie_rel", "qf_total", "t_total", "t_solve",
            "t_render", "n_images", "status", "error")


def level(outputs) -> str:
    """The checked ``outputs=`` value."""
    if outputs not in LEVELS:
        raise PsbenchError(f"outputs={outputs!r} is not known; valid choices: {', '.join(LEVELS)}")
    return outputs


def _base(out, cwd):
    p = Path(str(out)).expanduser()
    return p if p.is_absolute() else Path(cwd) / p


def sweep_dir(*, out, root, sweep, cwd) -> Path:
    """Folder of a sweep's run folders and comparison sheet."""
    return _base(out, cwd) if out else Path(root) / "out" / sweep


def run_dir(*, out, outputs, root, sweep, run_id, multi, cwd):
    """Folder of one run's outputs, or None with ``outputs=none``; checked with
    :func:`check_dir` (raises before any work when it holds foreign files)."""
    if level(outputs) == "none":
        return None
    if out and not multi:
        d = _base(out, cwd)
    else:
        d = sweep_dir(out=out, root=root, sweep=sweep, cwd=cwd) / run_id
    check_dir(d)
    return d


def check_dir(path) -> None:
    """Refuse a folder that exists, is not empty and was not written by psbench (it is
    replaced as a whole when the run's outputs are written)."""
    p = Path(path)
    if p.is_file():
        raise PsbenchError(f"out={str(p)!r} is a file; give a folder for the run's pictures")
    if p.is_dir() and not (p / MARKER).is_file() and any(p.iterdir()):
        raise PsbenchError(f"out={str(p)!r} holds files psbench did not write; give a new or "
                           "empty folder (the run's folder is replaced as a whole)")


def present(path) -> bool:
    """True when ``path`` holds a run's outputs (or when there are none to hold)."""
    return path is None or (Path(path) / MARKER).is_file()


def _clean(v):
    if isinstance(v, (np.generic,)):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if hasattr(v, "isoformat"):
        return v.isoformat()
    return v


def write_run(path, *, lvl, row, result, scene, line) -> float:
    """Write one run's outputs to ``path`` (replaced atomically as a whole); returns the
    seconds it took.

    Parameters
    ----------
    path : Path
    lvl : {"all", "pictures"}
    row : dict
        The run's results row.
    result : psbench Result
    scene : object with ``images``, ``lights``, ``mask``, ``normals`` and ``truth``
        (the rendered scene, or None for data read from a folder).
    line : str
        The printed row (stored in ``run.json``).
    """
    from ..io import atomic_dir, write_outputs
    from ..io._common import json_default
    from .._shared.files import atomic_write
    from . import spec as S

    t0 = time.perf_counter()
    truth = getattr(scene, "truth", None)
    outliers = None
    if truth is not None and getattr(truth, "highlight", None) is not None:
        outliers = np.asarray(truth.highlight, bool) | np.asarray(truth.shadow, bool)
    full = lvl == "all"
    with atomic_dir(path, overwrite=True) as tmp:
        files = write_outputs(tmp, result, object_mask=scene.object_mask, images=scene.images,
                              truth_normals=scene.normals, true_outliers=outliers,
                              arrays=full, ply=full, obj=full, per_image=False,
                              pixel_size=getattr(scene, "pixel_size", None))
        cfg = json.loads(row.get("config") or "{}")
        info = dict(run_id=row["run_id"], sweep=row.get("sweep"), row=line,
                    params={k: _clean(row.get(k)) for k in S.param_names()},
                    figures={k: _clean(row.get(k)) for k in _FIGURES},
                    lights_read=cfg.get("lights_read"), outputs=lvl,
                    files=sorted(files + [MARKER]))
        atomic_write(tmp / MARKER, json.dumps(info, indent=1, default=json_default),
                     fsync=False)
    return time.perf_counter() - t0


def copy_stored(src, dest) -> bool:
    """Copy a stored run's outputs folder ``src`` to ``dest`` (replaced atomically as a
    whole), for ``out=DIR`` on a run stored earlier; False when ``src`` holds none."""
    import shutil

    from ..io import atomic_dir

    src, dest = Path(src), Path(dest)
    if src.resolve() == dest.resolve() or not present(src) or src == dest:
        return False
    with atomic_dir(dest, overwrite=True) as tmp:
        for f in src.iterdir():
            if f.is_file():
                shutil.copy2(f, tmp / f.name)
    return True


def read_run_info(path) -> dict | None:
    """``run.json`` of a run folder (None when absent or unreadable)."""
    try:
        return json.loads((Path(path) / MARKER).read_text())
    except (OSError, ValueError):
        return None
