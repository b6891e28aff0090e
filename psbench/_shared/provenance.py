"""Where psbench's code came from: git commit and library versions.

One helper for every writer of provenance (results rows, reports). The git state is
that of the source tree psbench is imported from, and only when that tree is a git
checkout of psbench itself: an installed copy inside some other repository reports
no commit rather than the other repository's.
"""
from __future__ import annotations

import platform
import subprocess
from functools import lru_cache
from pathlib import Path

__all__ = ["git_state", "library_versions"]

#: distributions whose versions are recorded with every row
LIBRARIES = ("numpy", "scipy", "opencv-python-headless", "pandas", "pyarrow", "hydra-core",
             "omegaconf", "joblib", "submitit")


def _git(*args, cwd, timeout=10):
    return subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True,
                          timeout=timeout)


@lru_cache(maxsize=1)
def git_state() -> tuple[str | None, bool | None]:
    """``(sha, dirty)`` of the psbench checkout, ``(None, None)`` when not in one.

    ``dirty`` is True when tracked files differ from the commit (untracked files do not
    count); None when git could not tell.
    """
    pkg = Path(__file__).resolve().parents[1]
    try:
        top = _git("rev-parse", "--show-toplevel", cwd=pkg)
        if top.returncode != 0:
            return None, None
        root = Path(top.stdout.strip())
        if (root / "psbench" / "__init__.py").resolve() != (pkg / "__init__.py"):
            return None, None                 # psbench installed inside another repository
        sha = _git("rev-parse", "HEAD", cwd=root).stdout.strip() or None
        st = _git("status", "--porcelain", "--untracked-files=no", cwd=root, timeout=20)
        return sha, (bool(st.stdout.strip()) if st.returncode == 0 else None)
    except (OSError, subprocess.SubprocessError):
        return None, None


@lru_cache(maxsize=1)
def library_versions() -> dict[str, str | None]:
    """Python and :data:`LIBRARIES` versions (None for a library that is not installed)."""
    from importlib import metadata

    out = {"python": platform.python_version()}
    for name in LIBRARIES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out
