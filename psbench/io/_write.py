"""Writing folders atomically: data sets (DiLiGenT layout) and solve outputs."""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError, as_images, as_mask
from .._shared.deprecation import renamed_args
from .._shared.files import HOST, atomic_write
from ._common import PsbenchWarning, json_default
from ._images import write_image
from ._pictures import NORMAL_CODES, encode_normals

__all__ = ["atomic_dir", "write_dataset", "write_outputs", "encode_normals", "write_ply", "write_obj",
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
        # the writer's pid and host in the name: a later writer proves it dead (stale_partials)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{t.name}.partial-{os.getpid()}.{HOST}-",
                                         dir=t.parent))
        os.chmod(self.tmp, 0o777 & ~_umask())      # mkdtemp makes 0700: a normal folder
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


def _umask():
    old = os.umask(0)
    os.umask(old)
    return old


def stale_partials(folder, *, remove=True) -> list[Path]:
    """Partial folders (``.<name>.partial-<pid>.<host>-*``) in ``folder`` whose writer,
    a process on this host, no longer exists (killed with SIGKILL, a power cut);
    removed when ``remove``. Returns their paths."""
    out = []
    folder = Path(folder)
    if not folder.is_dir():
        return out
    for p in sorted(folder.glob(".*.partial-*")):
        tag = p.name.rsplit(".partial-", 1)[-1].rsplit("-", 1)[0]      # pid.host
        pid, _, host = tag.partition(".")
        if not (p.is_dir() and pid.isdigit() and host == HOST) or _alive(int(pid)):
            continue
        if remove:
            shutil.rmtree(p, ignore_errors=True)
        out.append(p)
    return out


def _alive(pid) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


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
    if not np.issubdtype(imgs.dtype, np.unsignedinteger):
        lo, hi = float(np.nanmin(imgs)), float(np.nanmax(imgs))
        if lo < 0.0 or hi > 1.0:       # written clipped: say so, the files lose those values
            n = int(np.count_nonzero((imgs < 0.0) | (imgs > 1.0)))
            warnings.warn(f"write_dataset: {n} image values outside [0, 1] (min {lo:g}, max "
                          f"{hi:g}) are clipped to [0, 1] in {path}; scale the images first "
                          "to keep them", PsbenchWarning, stacklevel=3)   # past renamed_args
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
def _mesh(height, object_mask, quads=False):
    """Vertices (n, 3) float32 and triangles (m, 3) int32 of a height map (see write_ply);
    ``quads``: one (m, 4) quad (bl, br, tr, tl) per 2x2 block instead of two triangles."""
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
    if quads:
        return verts, np.stack([cc[quad], d[quad], b[quad], a[quad]], axis=1).astype(np.int32)
    # y is up, so the bottom row is lower: CCW from +z is (bl, br, tr) and (bl, tr, tl)
    t1 = np.stack([cc[quad], d[quad], b[quad]], axis=1)
    t2 = np.stack([cc[quad], b[quad], a[quad]], axis=1)
    return verts, np.concatenate([t1, t2]).astype(np.int32)


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def write_ply(path, height, *, object_mask=None, binary=True):
    """Write a height map as a triangle mesh (PLY).

    Vertices are the pixels of ``object_mask`` (default all) at ``(x, y, z) = (c - (W-1)/2, (H-1)/2 - r, height)``
    (pixel units, psbench's frame); every 2x2 pixel block whose four corners are in
    the object mask gives two triangles (counter-clockwise seen from +z). Vectorized.
    Returns ``(n_vertices, n_faces)``.
    """
    verts, faces = _mesh(height, object_mask)
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

    atomic_write(path, write, fsync=False)
    return len(verts), len(faces)


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def write_obj(path, height, *, object_mask=None):
    """Write a height map as a Wavefront OBJ mesh (text; the vertices of :func:`write_ply`,
    one quad per 2x2 pixel block whose corners are in the object, counter-clockwise seen
    from +z, 1-based). Returns ``(n_vertices, n_faces)``."""
    verts, faces = _mesh(height, object_mask, quads=True)

    def write(f):
        f.write(b"# psbench height map mesh (pixel units; x right, y up, z height)\n")
        # one C-level format call per block: no Python loop over vertices
        for lo in range(0, len(verts), 1 << 16):
            v = verts[lo:lo + (1 << 16)].astype(np.float64)
            f.write((("v %.4f %.4f %.4f\n" * len(v)) % tuple(v.ravel())).encode("ascii"))
        for lo in range(0, len(faces), 1 << 16):
            t = faces[lo:lo + (1 << 16)] + 1
            f.write((("f %d %d %d %d\n" * len(t)) % tuple(t.ravel().tolist())).encode("ascii"))

    atomic_write(path, write, fsync=False)
    return len(verts), len(faces)


@renamed_args(renamed={"mask": "object_mask"})
def write_outputs(path, result, *, object_mask=None, images=None, truth_normals=None,
                  true_outliers=None, height=True, ply=True, obj=True, binary_ply=True,
                  pictures=True, arrays=True, per_image=True, code="field", pixel_size=None):
    """Write a solve result (data and pictures) to a folder, each file atomically.

    Data, each array in its own compressed ``.npz`` under its own name
    (``np.load("normals.npz")["normals"]``; deflate at level 1, which keeps most of the
    size gain of ``np.savez_compressed`` at a fraction of its time): ``normals.npz``
    (H, W, 3) float32, ``albedo.npz``, ``valid.npz`` (k, H, W) bool (True = used),
    ``weights.npz`` / ``ring_weights.npz`` when the result has them, ``ne.npz``
    (per-pixel angular error in degrees, NaN outside the object) with ``truth_normals``,
    ``height.npz`` (pixel units) with ``mesh.ply`` and ``mesh.obj``; with ``pixel_size``
    also ``height.x3p``, the heights in µm as an ISO 25178-72 file (NaN outside the
    object), whatever ``arrays`` says.

    Pictures (8-bit PNG): ``normals.png`` (``code="field"``: RGB = (n + 1) / 2 as
    DiLiGenT; ``"thesis"``: Fig. 5.17), ``albedo.png`` (99th percentile over the object
    = white), ``object_mask.png``, ``input.png`` (with ``images``: the image lit nearest
    the camera axis), ``truth.png`` and ``error.png`` (NE map, magma over 0-20 deg with a
    colour bar; ``ne_map.png`` the same map without bar and title) with
    ``truth_normals``, ``mask.png`` (every image with the observations
    the mask excluded coloured; TP/FP/FN with ``true_outliers``), ``weights.png`` /
    ``ring_weights.png`` (viridis with a colour bar), ``height.png`` (shaded oblique view
    of the heights). ``per_image=True`` also writes ``valid/NNN.png`` (0/255) and
    ``weights/NNN.png`` (16-bit, divided by the max) for every image.

    Parameters
    ----------
    path : str or Path
    result : psbench Result (or any object with ``.normals`` and optional
        ``.albedo .height .valid .weights .ring_weights .lights``)
    object_mask : (H, W) bool, optional
        The object region (default all).
    images : (k, H, W) float, optional
        The input images (``input.png`` and the background of ``mask.png``).
    truth_normals : (H, W, 3), optional
        Ground truth: ``truth.png``, ``ne.npz``, ``error.png``.
    true_outliers : (k, H, W) bool, optional
        True highlights and shadows (rendered scenes): colours ``mask.png`` as
        TP / FP / FN.
    height : bool
        Integrate the normals when the result holds no heights (``height.npz``,
        meshes, ``height.png``); False writes no heights.
    ply, obj, binary_ply : bool
        Which meshes to write.
    pictures : bool
        False writes the ``.npz`` data and meshes only.
    arrays : bool
        False writes no ``.npz`` file (pictures and meshes only).
    per_image : bool
        Also one PNG per image for ``valid`` and the weights.
    code : {"field", "thesis"}
        Colour code of ``normals.png`` and ``truth.png``.
    pixel_size : float, optional
        µm per pixel, when known (a cartridge case, an X3P scan, a calibrated capture):
        the heights are also written as ``height.x3p`` in µm.

    Returns
    -------
    list of str
        The written files, relative to ``path``.
    """
    from . import _pictures as P

    out = Path(path)
    out.mkdir(parents=True, exist_ok=True)
    n = np.asarray(result.normals, dtype=np.float32)
    H, W = n.shape[:2]
    m = as_mask(object_mask, (H, W), "object_mask")
    if code not in NORMAL_CODES:
        raise PsbenchError(f"code={code!r} is not known; valid choices: {', '.join(NORMAL_CODES)}")
    written = []

    def save_npy(name, arr):
        if not arrays:
            return
        written.append(save_npz(out / name, arr))

    def save_pic(name, rgb):
        if pictures:
            P.write_png(out / name, rgb)
            written.append(name)

    save_npy("normals", n)
    save_pic("normals.png", P.normal_rgb(n, m, code=code))
    save_pic("object_mask.png", (m * 255).astype(np.uint8))
    alb = getattr(result, "albedo", None)
    if alb is not None:
        alb = np.asarray(alb, dtype=np.float32)
        save_npy("albedo", alb)
        save_pic("albedo.png", P.gray(alb, m))
    imgs = None if images is None else np.asarray(images, dtype=np.float32)
    if imgs is not None:
        save_pic("input.png", P.gray(imgs[_frontal(result, imgs)], m))
    if truth_normals is not None:
        from ..metrics.errors import normal_error_map

        t = np.asarray(truth_normals, dtype=np.float32)
        ne = np.where(m, normal_error_map(n, t), np.nan).astype(np.float32)
        save_npy("ne", ne)
        save_pic("truth.png", P.normal_rgb(t, m, code=code))
        mean = float(np.nanmean(ne)) if m.any() else float("nan")
        save_pic("ne_map.png", P.ne_map(ne, m))
        save_pic("error.png", P.error_picture(ne, m, title=f"mean NE {mean:.2f} deg "
                                              f"(angle to the true normal)"))
    ve = getattr(result, "ve", None) if imgs is not None else None
    if ve is not None:  # ground-truth-free: written for real data as well
        vm = np.where(m, ve.map, np.nan).astype(np.float32)
        save_npy("ve.npy", vm)
        save_pic("ve.png", P.ve_picture(vm, m, title=f"mean ve {ve.mean:.4f} (held-out "
                                         f"error / pixel intensity)"))
    fb = getattr(result, "fallback", None)
    if fb is not None:  # where the richer fit fell back to its start (solve.fallback)
        fb = np.asarray(fb, dtype=bool) & m
        save_npy("fallback", fb)
        frac = float(fb[m].mean()) if m.any() else 0.0
        bg = None if imgs is None else imgs[_frontal(result, imgs)]
        save_pic("fallback.png", P.fallback_picture(fb, m, background=bg, title=(
            f"fell back on {100 * frac:.1f} % of the object pixels (orange)")))
    _write_masks(out, result, m, imgs, true_outliers, save_npy, save_pic, per_image,
                 written)
    hgt = getattr(result, "height", None)
    if hgt is None and height:
        try:
            from ..integrate.poisson import integrate
            hgt = integrate(n, object_mask=m)
        except Exception as e:  # noqa: BLE001 - integration failed: no heights, say why
            warnings.warn(f"no height written: {e}", PsbenchWarning, stacklevel=2)
    if hgt is not None and height:
        hgt = np.asarray(hgt, dtype=np.float32)
        save_npy("height", hgt)
        if pixel_size is not None:
            from .x3p import write_x3p

            px = float(pixel_size)
            write_x3p(out / "height.x3p", np.where(m, hgt * np.float32(px), np.nan),
                      pixel_size=px, comment="heights integrated from photometric stereo "
                      "normals by psbench")
            written.append("height.x3p")
        if ply:
            write_ply(out / "mesh.ply", hgt, object_mask=m, binary=binary_ply)
            written.append("mesh.ply")
        if obj:
            write_obj(out / "mesh.obj", hgt, object_mask=m)
            written.append("mesh.obj")
        if pictures:
            from ._relief import height_picture

            rel = height_picture(hgt, m, pixel_size=pixel_size)
            save_pic("height.png", P.titled(rel, "heights integrated from the normals (to scale)",
                                            size=P.text_px(max(rel.shape[:2]), least=16)))
    return written


def save_npz(path, arr, *, level=1):
    """Write one array as a compressed ``.npz`` (key: the file's stem), atomically.

    Parameters
    ----------
    path : str or Path
        Target; ``.npz`` replaces any suffix it has.
    arr : array_like
    level : int
        zlib level (1: fast; numpy's ``savez_compressed`` uses the default 6).

    Returns
    -------
    str
        The file's name.
    """
    import zipfile

    p = Path(path).with_suffix(".npz")
    a = np.asanyarray(arr)

    def write(fh):
        with zipfile.ZipFile(fh, "w", compression=zipfile.ZIP_DEFLATED,
                             compresslevel=level) as zf:
            with zf.open(p.stem + ".npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, a, allow_pickle=False)

    atomic_write(p, write, fsync=False)
    return p.name


def _frontal(result, images):
    """Index of the image lit nearest the camera axis (fewest shadows), else 0."""
    lay = getattr(result, "lights", None)
    d = getattr(lay, "directions", None)
    if d is None or len(d) != len(images):
        return 0
    return int(np.argmax(np.asarray(d)[:, 2]))


def _write_masks(out, result, m, imgs, true_outliers, save_npy, save_pic, per_image, written):
    """valid / weights / ring_weights: data, overview pictures and per-image PNGs."""
    from . import _pictures as P

    for name in ("valid", "weights", "ring_weights"):
        a = getattr(result, name, None)
        if a is None or np.ndim(a) != 3:
            continue
        a = np.asarray(a)
        save_npy(name, a)
        if name == "valid":
            base = imgs if imgs is not None and imgs.shape == a.shape else np.full(a.shape, 0.6)
            to = None if true_outliers is None else np.asarray(true_outliers, bool)
            if to is not None and to.shape != a.shape:
                raise PsbenchError(f"true_outliers must have shape {a.shape}, got {to.shape}")
            save_pic("mask.png", P.valid_picture(base, a, m, truth=to))
        else:
            zen = (getattr(result, "info", None) or {}).get("ring_zeniths")
            rings = name == "ring_weights" and zen is not None and len(zen) == len(a)
            save_pic(f"{name}.png", P.weights_picture(
                a, m, title="ring weight" if name == "ring_weights" else "weight",
                vmax=1.0 if name == "ring_weights" else None,
                labels=[f"{z:g}°" for z in zen] if rings else None))   # the ring's zenith
        if not per_image:
            continue
        (out / name).mkdir(exist_ok=True)
        mx = float(a.max()) or 1.0
        for i, v in enumerate(a):
            dst = out / name / f"{i + 1:03d}.png"
            tmp = dst.with_name(".tmp-" + dst.name)
            if name == "valid":
                write_image(tmp, v.astype(np.uint8) * 255, bits=8)
            else:
                write_image(tmp, v / mx)
            os.replace(tmp, dst)
            written.append(f"{name}/{i + 1:03d}.png")
