"""Writing folders atomically: data sets (DiLiGenT layout) and solve outputs."""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

from .._checks import PsbenchError, as_images, as_mask
from .._deprecate import renamed_args
from .._fs import atomic_write
from ._common import PsbenchWarning, json_default
from ._images import write_image

__all__ = ["atomic_dir", "write_dataset", "write_outputs", "encode_normals", "write_ply",
           "fmt_rows"]


# --------------------------------------------------------------------------- writing
class atomic_dir:
    """Context manager: build a folder in a temp dir beside ``target`` and rename it
    into place on success; on any error (or KeyboardInterrupt) the temp dir is removed
    and ``target`` is left untouched. Yields the temp dir Path.

    ``overwrite=True`` replaces an existing target (old one moved aside, then removed).
    """

    def __init__(self, target, *, overwrite=False):
        self.target = Path(target)
        self.overwrite = overwrite
        self.tmp = None

    def __enter__(self):
        t = self.target
        if t.exists() and not self.overwrite:
            raise PsbenchError(f"output folder {str(t)!r} already exists (pass overwrite=True to replace it)")
        t.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{t.name}.partial-", dir=t.parent))
        return self.tmp

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            return False
        t = self.target
        if t.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{t.name}.old-", dir=t.parent))
            os.replace(t, old / "x")
            os.replace(self.tmp, t)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(self.tmp, t)
        return False


def fmt_rows(a):
    """Rows of ``a`` as text, one line each, full float64 precision."""
    return "".join(" ".join(repr(float(v)) for v in row) + "\n" for row in np.atleast_2d(a))


@renamed_args(positional=("object_mask", "normals"), renamed={"mask": "object_mask"})
def write_dataset(path, images, lights, *, object_mask=None, normals=None, bits=16, meta=None,
                  names=None, intensities=None, overwrite=False, extra=None):
    """Write a DiLiGenT-layout folder atomically (temp dir beside ``path``, then rename).

    Parameters
    ----------
    path : str or Path
        Target folder (must not exist unless ``overwrite``).
    images : (k, H, W) float in [0, 1] or uint8/uint16
        Written as ``001.png`` ... at ``bits`` (8/12/16; 12 in 16-bit containers,
        recorded as ``"bits": 12`` in psbench.json).
    lights : (k, 3) array_like or Layout
        Written with full float64 precision; ring ids (and near-light positions,
        if the layout has them) go to psbench.json.
    object_mask : (H, W) bool, optional
        ``mask.png`` (0/255).
    normals : (H, W, 3), optional
        ``normals.npy`` (float32).
    meta : dict, optional
        Written to ``psbench.json`` (with ``bits``, ``ring``, ``k``).
    names : list of str, optional
        File names (default ``001.png`` ...).
    intensities : (k,) or (k, 3), optional
        ``light_intensities.txt`` (default ones, k x 3).
    extra : dict name -> callable(tmpdir), optional
        Extra writers run inside the temp dir before the rename.
    """
    from ..lights import Layout, layout as _layout

    raw_int = np.asarray(images)
    if raw_int.ndim != 3:
        raise PsbenchError(f"images must have shape (k, H, W), got {raw_int.shape}")
    imgs = raw_int if np.issubdtype(raw_int.dtype, np.unsignedinteger) else as_images(raw_int)
    k, H, W = imgs.shape
    lay = lights if isinstance(lights, Layout) else _layout(np.asarray(lights, dtype=float))
    if lay.k != k:
        raise PsbenchError(f"lights has {lay.k} directions for {k} images")
    m = None if object_mask is None else as_mask(object_mask, (H, W), "object_mask")
    if normals is not None:
        normals = np.asarray(normals, dtype=np.float32)
        if normals.shape != (H, W, 3):
            raise PsbenchError(f"normals must have shape ({H}, {W}, 3), got {normals.shape}")
    if names is None:
        names = [f"{i + 1:03d}.png" for i in range(k)]
    if len(names) != k:
        raise PsbenchError(f"names has {len(names)} entries for {k} images")
    inten = np.ones((k, 3)) if intensities is None else np.asarray(intensities, dtype=float)
    if inten.shape[0] != k:
        raise PsbenchError(f"intensities has {inten.shape[0]} rows for {k} images")
    md = dict(meta or {})
    md.setdefault("bits", int(bits) if not np.issubdtype(imgs.dtype, np.unsignedinteger)
                  else int(np.iinfo(imgs.dtype).bits))
    md.setdefault("ring", [int(r) for r in lay.ring])
    md.setdefault("k", k)
    if lay.positions is not None:
        md.setdefault("positions", np.asarray(lay.positions).tolist())
    with atomic_dir(path, overwrite=overwrite) as tmp:
        for n, img in zip(names, imgs):
            write_image(tmp / n, img, bits=bits)
        (tmp / "filenames.txt").write_text("".join(n + "\n" for n in names))
        (tmp / "light_directions.txt").write_text(fmt_rows(lay.directions))
        (tmp / "light_intensities.txt").write_text(fmt_rows(inten.reshape(k, -1)))
        if m is not None:
            write_image(tmp / "mask.png", (m * 255).astype(np.uint8))
        if normals is not None:
            np.save(tmp / "normals.npy", normals)
        if extra:
            for fn in extra.values():
                fn(tmp)
        (tmp / "psbench.json").write_text(json.dumps(md, indent=1, default=json_default))
    return Path(path)


# --------------------------------------------------------------------------- outputs
@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def encode_normals(normals, *, object_mask=None):
    """Fig. 5.17 colour code: [r, g, b] = [(nx+1)/2, (ny+1)/2, nz], (H, W, 3) float in [0, 1].

    nz < 0 (invalid for a visible surface) is clipped to 0; pixels outside
    ``object_mask`` (optional, (H, W) bool) are black.
    """
    n = np.asarray(normals, dtype=np.float64)
    rgb = np.stack([(n[..., 0] + 1) / 2, (n[..., 1] + 1) / 2, n[..., 2]], axis=-1)
    rgb = np.clip(rgb, 0.0, 1.0)
    if object_mask is not None:
        rgb[~np.asarray(object_mask, bool)] = 0.0
    return rgb


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def write_ply(path, height, *, object_mask=None, binary=True):
    """Write a height map as a triangle mesh (PLY).

    Vertices are the pixels of ``object_mask`` (default all) at ``(x, y, z) = (c - (W-1)/2, (H-1)/2 - r, height)``
    (pixel units, psbench's frame); every 2x2 pixel block whose four corners are in
    the object mask gives two triangles (counter-clockwise seen from +z). Vectorized.
    """
    h = np.asarray(height, dtype=np.float64)
    if h.ndim != 2:
        raise PsbenchError(f"height must have shape (H, W), got {h.shape}")
    H, W = h.shape
    m = as_mask(object_mask, (H, W), "object_mask") & np.isfinite(h)
    idx = -np.ones((H, W), dtype=np.int64)
    idx[m] = np.arange(int(m.sum()))
    r, c = np.nonzero(m)
    verts = np.stack([c - (W - 1) / 2.0, (H - 1) / 2.0 - r, h[m]], axis=1).astype(np.float32)
    a, b = idx[:-1, :-1], idx[:-1, 1:]   # top-left, top-right
    cc, d = idx[1:, :-1], idx[1:, 1:]    # bottom-left, bottom-right
    quad = (a >= 0) & (b >= 0) & (cc >= 0) & (d >= 0)
    # y is up, so the bottom row is lower: CCW from +z is (bl, br, tr) and (bl, tr, tl)
    t1 = np.stack([cc[quad], d[quad], b[quad]], axis=1)
    t2 = np.stack([cc[quad], b[quad], a[quad]], axis=1)
    faces = np.concatenate([t1, t2]).astype(np.int32)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fmt = "binary_little_endian" if binary else "ascii"
    header = (f"ply\nformat {fmt} 1.0\ncomment psbench height map mesh (pixel units)\n"
              f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    def write(f):
        f.write(header.encode("ascii"))
        if binary:
            f.write(verts.astype("<f4").tobytes())
            rec = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", 3)])
            rec["n"] = 3
            rec["v"] = faces
            f.write(rec.tobytes())
        else:
            np.savetxt(f, verts, fmt="%.6g")
            np.savetxt(f, np.hstack([np.full((len(faces), 1), 3), faces]), fmt="%d")

    atomic_write(p, write, fsync=False)
    return len(verts), len(faces)


@renamed_args(renamed={"mask": "object_mask"})
def write_outputs(path, result, *, object_mask=None, ply=True, binary_ply=True):
    """Write a solve result to a folder.

    Files: ``normals.npy`` (H, W, 3) float32, ``normals.png`` (16-bit RGB, Fig. 5.17
    code), ``albedo.npy``, ``albedo.png`` (16-bit, divided by the max albedo over the
    mask), ``height.npy`` and ``mesh.ply`` (when the result has a height or
    :func:`psbench.integrate` is available), ``valid.npy`` + ``valid/NNN.png``
    (0/255, True = used), ``weights.npy`` + ``weights/NNN.png`` (16-bit, divided by
    the max weight), likewise ``ring_weights`` (WPS). Each file is written to a temp name and renamed.

    Parameters
    ----------
    path : str or Path
    result : psbench Result (or any object with ``.normals`` and optional
        ``.albedo .height .valid .weights .ring_weights``)
    object_mask : (H, W) bool, optional
        The object region (default all).
    """
    out = Path(path)
    out.mkdir(parents=True, exist_ok=True)
    n = np.asarray(result.normals, dtype=np.float32)
    H, W = n.shape[:2]
    m = as_mask(object_mask, (H, W), "object_mask")
    written = []

    def save_npy(name, arr):
        atomic_write(out / name, lambda fh: np.save(fh, arr), fsync=False)
        written.append(name)

    def save_png(name, img, bits=16):
        dst = out / name
        tmp = dst.with_name(".tmp-" + dst.name)
        write_image(tmp, img, bits=bits)
        os.replace(tmp, dst)
        written.append(name)

    save_npy("normals.npy", n)
    save_png("normals.png", encode_normals(n, object_mask=m))
    alb = getattr(result, "albedo", None)
    if alb is not None:
        alb = np.asarray(alb, dtype=np.float32)
        save_npy("albedo.npy", alb)
        mx = float(alb[m].max()) if m.any() else 0.0
        save_png("albedo.png", np.where(m, alb / mx, 0) if mx > 0 else np.zeros_like(alb))
    hgt = getattr(result, "height", None)
    if hgt is None:
        try:
            from ..integrate import integrate
            hgt = integrate(n, object_mask=m)
        except Exception as e:  # integrate not available or failed: skip the mesh
            warnings.warn(f"no height written: {e}", PsbenchWarning, stacklevel=2)
    if hgt is not None:
        hgt = np.asarray(hgt, dtype=np.float32)
        save_npy("height.npy", hgt)
        if ply:
            write_ply(out / "mesh.ply", hgt, object_mask=m, binary=binary_ply)
            written.append("mesh.ply")
    for name, scale in (("valid", None), ("weights", "max"), ("ring_weights", "max")):
        a = getattr(result, name, None)
        if a is None:
            continue
        a = np.asarray(a)
        if a.ndim != 3:
            continue
        save_npy(f"{name}.npy", a)
        (out / name).mkdir(exist_ok=True)
        if name == "valid":
            for i, v in enumerate(a):
                save_png(f"{name}/{i + 1:03d}.png", (v.astype(np.uint8) * 255), bits=8)
        else:
            mx = float(a.max()) or 1.0
            for i, v in enumerate(a):
                save_png(f"{name}/{i + 1:03d}.png", v / mx)
    return written
