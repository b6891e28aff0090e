"""Atomic file writes shared by every psbench writer.

A file is written under a hidden temporary name in its own folder, flushed to disk and
renamed over the target with ``os.replace``; readers see either the old file or the
complete new one, never a partial file. A writer that fails (or is interrupted) leaves
no temporary file behind.
"""
from __future__ import annotations

import os
import secrets
import socket
from pathlib import Path

__all__ = ["atomic_write", "temp_name"]


def temp_name(path) -> Path:
    """A unique hidden temporary name beside ``path``
    (``.<name>.tmp.<pid>.<hex>.<host>``: the writer's pid and host let a cleaner prove
    that a leftover temporary file's writer is dead)."""
    path = Path(path)
    return path.with_name(f".{path.name}.tmp.{os.getpid()}.{secrets.token_hex(4)}.{HOST}")


#: this machine's name as written into temporary names (no separators)
HOST = "".join(c if c.isalnum() or c in "-_" else "_" for c in socket.gethostname()) or "host"


def atomic_write(path, data, *, fsync=True) -> Path:
    """Write ``data`` to ``path`` atomically.

    Parameters
    ----------
    path : str or Path
        Target file; its folder is created if needed.
    data : bytes, str or callable
        Content, or a function ``write(fh)`` that writes into the open binary file.
    fsync : bool
        Flush the file to disk before the rename (default True).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temp_name(path)
    try:
        with open(tmp, "wb") as fh:
            if callable(data):
                data(fh)
            else:
                fh.write(data.encode("utf-8") if isinstance(data, str) else data)
            if fsync:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink()
        except OSError:
            pass
        raise
    return path
