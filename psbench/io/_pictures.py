"""Pictures of a solve: 8-bit RGB arrays drawn with numpy, OpenCV colour maps and Pillow text.

No matplotlib figure is made here (a figure costs more than the solve of a small scene):
colour maps come from OpenCV's look-up tables, labels and colour bars are drawn with
Pillow in the DejaVu Sans font matplotlib ships. Every function returns (H, W, 3) uint8
RGB; :func:`write_png` writes one atomically.

Conventions: normal maps are coded as the field does (DiLiGenT: RGB = (n + 1) / 2);
intensities (images, albedo) are scaled so that the 99th percentile over the object is
white, so one specular spot cannot make the picture black; per-pixel normal error uses
the perceptual ``magma`` map over a fixed 0-20 deg range (the report's range), values
above it saturate.
"""
from __future__ import annotations

import importlib.util
from functools import lru_cache
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from .._shared.deprecation import renamed_args
from .._shared.files import atomic_write
from ._common import cv2 as _cv2

__all__ = ["NE_MAX", "BACKGROUND", "normal_rgb", "gray", "colorize", "ne_map", "ve_picture",
           "fallback_picture",
           "error_picture", "valid_picture", "weights_picture", "height_picture",
           "titled", "montage", "color_bar", "hstack", "object_box", "write_png", "text_size",
           "font", "nice_ticks", "text_px", "scale_bar"]

NE_MAX = 20.0                      # deg: colour range of every NE map (as the report's panels)
BACKGROUND = (255, 255, 255)       # outside the object in colour-mapped pictures
_INK = (20, 20, 20)
_CMAPS = {"magma": "COLORMAP_MAGMA", "viridis": "COLORMAP_VIRIDIS",
          "inferno": "COLORMAP_INFERNO", "gray": None}


# --------------------------------------------------------------------------- basics
NORMAL_CODES = ("field", "thesis")


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def encode_normals(normals, *, object_mask=None, code="field"):
    """Normals as RGB, (H, W, 3) float in [0, 1].

    ``code="field"`` (default): [r, g, b] = (n + 1) / 2, the convention of DiLiGenT and
    most photometric stereo papers (a frontal normal is (0.5, 0.5, 1)). ``code="thesis"``:
    Fig. 5.17's [(nx + 1) / 2, (ny + 1) / 2, nz] (nz < 0 clipped to 0). Pixels outside
    ``object_mask`` (optional, (H, W) bool) are black.
    """
    if code not in NORMAL_CODES:
        raise PsbenchError(f"code={code!r} is not known; valid choices: {', '.join(NORMAL_CODES)}")
    n = np.asarray(normals, dtype=np.float64)
    blue = (n[..., 2] + 1) / 2 if code == "field" else n[..., 2]
    rgb = np.clip(np.stack([(n[..., 0] + 1) / 2, (n[..., 1] + 1) / 2, blue], axis=-1), 0.0, 1.0)
    if object_mask is not None:
        rgb[~np.asarray(object_mask, bool)] = 0.0
    return rgb


def normal_rgb(normals, object_mask=None, *, code="field"):
    """Normals as 8-bit RGB: ``field`` (DiLiGenT) (n + 1) / 2, or ``thesis`` (Fig. 5.17)
    [(nx + 1) / 2, (ny + 1) / 2, nz]. Outside ``object_mask`` black."""
    return _u8(encode_normals(normals, object_mask=object_mask, code=code))


def gray(image, object_mask=None, *, pct=99.0):
    """A linear intensity image as 8-bit grey RGB, scaled so that the ``pct`` percentile
    over ``object_mask`` is white (values above saturate); outside the object black."""
    img = np.asarray(image, dtype=np.float32)
    m = np.ones(img.shape, bool) if object_mask is None else np.asarray(object_mask, bool)
    vals = img[m & np.isfinite(img)]
    top = float(np.percentile(vals, pct)) if vals.size else 0.0
    g = np.clip(img / top, 0.0, 1.0) if top > 0 else np.zeros_like(img)
    g = np.where(m & np.isfinite(g), g, 0.0)
    return np.repeat(_u8(g)[..., None], 3, axis=-1)


def colorize(values, vmin, vmax, *, cmap="magma", valid=None, bad=BACKGROUND):
    """Values mapped linearly from [vmin, vmax] onto a colour map (OpenCV's tables).
    Pixels outside ``valid`` or not finite get the colour ``bad``."""
    v = np.asarray(values, dtype=np.float32)
    t = np.clip((v - vmin) / max(float(vmax - vmin), 1e-12), 0.0, 1.0)
    ok = np.isfinite(t) if valid is None else (np.asarray(valid, bool) & np.isfinite(t))
    idx = _u8(np.where(ok, t, 0.0))
    name = _CMAPS[cmap]
    if name is None:
        rgb = np.repeat(idx[..., None], 3, axis=-1)
    else:
        cv2 = _cv2()
        rgb = cv2.applyColorMap(idx, getattr(cv2, name))[..., ::-1]
    rgb = np.ascontiguousarray(rgb)
    rgb[~ok] = bad
    return rgb


def ne_map(ne, object_mask=None, *, vmax=NE_MAX):
    """A per-pixel normal error map (deg) in magma over [0, vmax], white outside."""
    return colorize(ne, 0.0, vmax, cmap="magma", valid=object_mask)


def object_box(object_mask, *, margin=0.03):
    """``(slice, slice)`` of the object's bounding box plus ``margin`` of the image side
    (the whole image when the mask is empty)."""
    m = np.asarray(object_mask, bool)
    if not m.any():
        return slice(None), slice(None)
    H, W = m.shape
    pad = int(round(margin * max(H, W)))
    rows, cols = np.nonzero(m.any(axis=1))[0], np.nonzero(m.any(axis=0))[0]
    return (slice(max(rows[0] - pad, 0), min(rows[-1] + pad + 1, H)),
            slice(max(cols[0] - pad, 0), min(cols[-1] + pad + 1, W)))


def _u8(x):
    return np.round(np.clip(np.asarray(x, dtype=np.float32), 0, 1) * 255).astype(np.uint8)


# --------------------------------------------------------------------------- text
@lru_cache(maxsize=8)
def font(size=16):
    """DejaVu Sans at ``size`` px (shipped with matplotlib; found without importing it),
    else Pillow's default font."""
    from PIL import ImageFont

    spec = importlib.util.find_spec("matplotlib")
    for base in (spec.submodule_search_locations or []) if spec else []:
        p = Path(base) / "mpl-data" / "fonts" / "ttf" / "DejaVuSans.ttf"
        if p.is_file():
            return ImageFont.truetype(str(p), size)
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1
        return ImageFont.load_default()


def text_px(side, *, least=14):
    """Font size (px) for text on a picture whose longer side is ``side`` px: ``least`` up
    to about 630 px, then 1/45 of the side, so that the text of a 2048 px picture reads
    as well as a 256 px one's when both are shown at the same size."""
    return int(max(least, round(float(side) / 45.0)))


def text_size(text, size=16):
    """(width, height) in px of ``text`` (one or more lines)."""
    from PIL import Image, ImageDraw

    box = ImageDraw.Draw(Image.new("RGB", (1, 1))).multiline_textbbox(
        (0, 0), text, font=font(size), spacing=3)
    return box[2] - box[0], box[3] - box[1]


def _draw(rgb, items):
    """Draw ``[(x, y, text, size, anchor)]`` on a copy of ``rgb``."""
    from PIL import Image, ImageDraw

    im = Image.fromarray(np.ascontiguousarray(rgb))
    d = ImageDraw.Draw(im)
    for x, y, text, size, anchor in items:
        d.multiline_text((x, y), text, fill=_INK, font=font(size), anchor=anchor, spacing=3,
                         align="center" if anchor[0] == "m" else "left")
    return np.asarray(im)


def _canvas(h, w, color=(255, 255, 255)):
    out = np.empty((h, w, 3), np.uint8)
    out[:] = color
    return out


def titled(rgb, title, *, size=16, pad=None):
    """``rgb`` with ``title`` (one or more lines) centred above it on white (``pad``:
    default a third of the font size, at least 6 px)."""
    pad = max(6, size // 3) if pad is None else pad
    tw, th = text_size(title, size)
    H, W = rgb.shape[:2]
    w = max(W, tw + 2 * pad)
    out = _canvas(H + th + 2 * pad, w)
    x0 = (w - W) // 2
    out[th + 2 * pad:, x0:x0 + W] = rgb
    return _draw(out, [(w / 2, pad, title, size, "ma")])


def nice_ticks(vmin, vmax, n=5):
    """About ``n`` round ticks (steps of 1, 2, 2.5 or 5 x 10^k) inside [vmin, vmax]."""
    span = float(vmax) - float(vmin)
    if not np.isfinite(span) or span <= 0:
        return np.array([float(vmin)])
    raw = span / max(n - 1, 1)
    k = 10.0 ** np.floor(np.log10(raw))
    step = next(m * k for m in (1, 2, 2.5, 5, 10) if m * k >= raw)
    first = np.ceil(vmin / step - 1e-9) * step
    ticks = np.arange(first, vmax + step * 1e-9, step)
    return np.round(ticks / step) * step + 0.0           # + 0.0: no "-0"


def color_bar(height, vmin, vmax, *, cmap="magma", label="", ticks=None, over=False, size=14):
    """A vertical colour bar ``height`` px tall with tick labels and a rotated-free label
    written above it; ``over`` marks the top as "and above". The bar's width, margins and
    ticks grow with the font ``size`` (:func:`text_px` of the picture it stands beside)."""
    f = max(1.0, size / 14.0)
    bar_w, margin, tick = int(round(18 * f)), int(round(8 * f)), int(round(4 * f))
    ticks = nice_ticks(vmin, vmax) if ticks is None else np.asarray(ticks, float)
    step = np.diff(ticks).min() if ticks.size > 1 else 0.0
    # the fewest decimals that write every tick exactly (0.25 needs 2, 0.5 needs 1)
    dec = next((d for d in range(7) if np.allclose(np.round(ticks, d), ticks, rtol=0,
                                                    atol=step * 1e-6)), 3) if step > 0 else 3
    labels = [f"{t:.{dec}f}" + ("+" if over and t == ticks[-1] else "") for t in ticks]
    lw = max(text_size(s, size)[0] for s in labels)
    top = text_size(label, size)[1] + 2 * margin if label else margin
    bh = max(height - top - margin, 20)
    ramp = np.linspace(vmax, vmin, bh, dtype=np.float32)[:, None].repeat(bar_w, axis=1)
    w = max(margin + bar_w + tick + 2 + lw + margin, text_size(label, size)[0] + 2 * margin)
    out = _canvas(top + bh + margin, w)
    out[top:top + bh, margin:margin + bar_w] = colorize(ramp, vmin, vmax, cmap=cmap)
    line = max(1, int(round(f)))
    out[top:top + bh, margin:margin + line] = _INK
    out[top:top + bh, margin + bar_w - line:margin + bar_w] = _INK
    out[top:top + line, margin:margin + bar_w] = _INK
    out[top + bh - line:top + bh, margin:margin + bar_w] = _INK
    items = [(margin, margin, label, size, "la")] if label else []
    for t, s in zip(ticks, labels):
        y = top + (vmax - t) / max(vmax - vmin, 1e-12) * (bh - 1)
        yi = int(round(y))
        out[max(yi - line // 2, 0):yi - line // 2 + line, margin + bar_w:margin + bar_w + tick] \
            = _INK
        items.append((margin + bar_w + tick + 2, y, s, size, "lm"))
    return _draw(out, items)


def scale_bar(rgb, px_per_um, *, size=14, where=(0.04, 0.94)):
    """``rgb`` with a scale bar of a round length in micrometres (about a fifth of its
    width) and its label; ``px_per_um``: picture pixels per micrometre along the
    horizontal; ``where``: the bar's left end, in fractions of the width and height."""
    H, W = rgb.shape[:2]
    if not (np.isfinite(px_per_um) and px_per_um > 0):
        return rgb
    want = 0.2 * W / px_per_um                               # um
    k = 10.0 ** np.floor(np.log10(want))
    um = max(m * k for m in (1, 2, 5) if m * k <= want * 1.0001)
    L = int(round(um * px_per_um))
    x0, y0 = int(where[0] * W), int(where[1] * H)
    t = max(2, size // 5)
    out = np.ascontiguousarray(rgb).copy()
    out[max(y0 - t, 0):y0, x0:x0 + L] = _INK
    text = f"{um:g} µm" if um < 1000 else f"{um / 1000:g} mm"
    return _draw(out, [(x0 + L / 2, y0 - t - 3, text, size, "md")])


def hstack(*pics, gap=8):
    """Pictures side by side, top-aligned, on white."""
    h = max(p.shape[0] for p in pics)
    w = sum(p.shape[1] for p in pics) + gap * (len(pics) - 1)
    out = _canvas(h, w)
    x = 0
    for p in pics:
        out[:p.shape[0], x:x + p.shape[1]] = p
        x += p.shape[1] + gap
    return out


def montage(tiles, *, ncols=None, labels=None, size=14, gap=4, max_width=1200):
    """Tiles (equal shapes) in a grid, each under its label; scaled down so the grid
    is at most ``max_width`` px wide."""
    cv2 = _cv2()
    n = len(tiles)
    ncols = ncols or int(np.ceil(np.sqrt(n * 1.6)))
    ncols = max(1, min(ncols, n))
    th, tw = tiles[0].shape[:2]
    scale = min(1.0, (max_width - gap * (ncols - 1)) / (ncols * tw))
    if scale < 1.0:
        th, tw = max(1, int(th * scale)), max(1, int(tw * scale))
        tiles = [cv2.resize(t, (tw, th), interpolation=cv2.INTER_AREA) for t in tiles]
    lh = text_size("Ag", size)[1] + 4 if labels else 0
    nrows = int(np.ceil(n / ncols))
    out = _canvas(nrows * (th + lh + gap) - gap, ncols * (tw + gap) - gap)
    items = []
    for i, t in enumerate(tiles):
        r, c = divmod(i, ncols)
        y, x = r * (th + lh + gap), c * (tw + gap)
        out[y + lh:y + lh + th, x:x + tw] = t
        if labels:
            items.append((x + tw / 2, y, str(labels[i]), size, "ma"))
    return _draw(out, items) if items else out


def write_png(path, rgb):
    """Write an 8-bit RGB (or grey) picture as PNG atomically; returns the path."""
    cv2 = _cv2()
    a = np.ascontiguousarray(rgb)
    if a.ndim == 3 and (a[..., 0] == a[..., 1]).all() and (a[..., 0] == a[..., 2]).all():
        a = np.ascontiguousarray(a[..., 0])        # grey: one channel, a third of the work
    # fast settings: pictures are written on every run (run-length strategy, level 1)
    ok, buf = cv2.imencode(".png", a[..., ::-1] if a.ndim == 3 else a,
                           [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY,
                            cv2.IMWRITE_PNG_STRATEGY_RLE])
    if not ok:  # pragma: no cover - OpenCV refuses only unsupported arrays
        raise RuntimeError(f"could not encode {path}")
    return atomic_write(path, buf.tobytes(), fsync=False)


# --------------------------------------------------------------------------- pictures
def error_picture(ne, object_mask=None, *, vmax=NE_MAX, title=None):
    """NE map with a colour bar (deg) and, when given, a title (e.g. the mean NE)."""
    img = ne_map(ne, object_mask, vmax=vmax)
    fs = text_px(max(img.shape[:2]))                      # text grows with the picture
    bar = color_bar(img.shape[0], 0.0, vmax, label="NE (deg)", over=True, size=fs)
    pic = hstack(img, bar, gap=fs // 2)
    return titled(pic, title, size=text_px(max(img.shape[:2]), least=16)) if title else pic


def ve_picture(ve, object_mask=None, *, title=None):
    """Validation-error map (:mod:`psbench.solve.validation`, relative to each pixel's
    mean intensity) in magma over [0, the object's 99th percentile], with a colour bar;
    undefined pixels white. Needs no ground truth."""
    ve = np.asarray(ve, dtype=np.float32)
    ok = np.isfinite(ve) if object_mask is None else (np.isfinite(ve) & object_mask)
    vmax = float(np.percentile(ve[ok], 99)) if ok.any() else 1.0
    vmax = vmax if vmax > 0 else 1.0
    img = colorize(np.where(ok, ve, 0.0), 0.0, vmax, valid=ok)
    fs = text_px(max(img.shape[:2]))
    bar = color_bar(img.shape[0], 0.0, vmax, label="ve (held-out |e| / mean I)", over=True,
                    size=fs)
    pic = hstack(img, bar, gap=fs // 2)
    return titled(pic, title, size=text_px(max(img.shape[:2]), least=16)) if title else pic


#: colour of the pixels that fell back (fallback_picture)
FALLBACK_RGB = (230, 120, 20)


def fallback_picture(fallback, object_mask=None, *, background=None, title=None):
    """The pixels where a method fell back to its simpler answer
    (:mod:`psbench.solve.fallback`) in orange over ``background`` ((H, W) intensities,
    e.g. the frontal image, in grey, black outside the object; None: the object in
    light grey on white). Needs no ground truth."""
    fb = np.asarray(fallback, dtype=bool)
    m = np.ones(fb.shape, bool) if object_mask is None else np.asarray(object_mask, bool)
    if background is None:
        pic = np.where(m[..., None], np.uint8(200), np.uint8(255)).repeat(3, axis=-1)
        pic = np.ascontiguousarray(pic, dtype=np.uint8)
    else:
        pic = gray(background, m).copy()
    pic[fb & m] = FALLBACK_RGB
    return titled(pic, title) if title else pic


def valid_picture(images, valid, object_mask=None, *, truth=None, max_width=1200):
    """Each image in grey with its excluded observations coloured, in a grid.

    Without ``truth``: excluded (``valid`` False) red. With ``truth`` ((k, H, W) bool,
    true highlights and shadows): TP green (excluded, truly corrupted), FP blue
    (excluded, clean), FN red (used, truly corrupted); legend below. Tiles are cropped to
    the object and shrunk before they are coloured (a pixel is coloured when at least half
    of the pixels it covers are).
    """
    cv2 = _cv2()
    imgs = np.asarray(images, dtype=np.float32)
    bad = ~np.asarray(valid, bool)
    k = imgs.shape[0]
    m = np.ones(imgs.shape[1:], bool) if object_mask is None else np.asarray(object_mask, bool)
    used = float((~bad)[:, m].mean()) if m.any() else 1.0
    # one scale for every image: intensities stay comparable across lights
    top = float(np.percentile(imgs[:, m], 99.0)) if m.any() else 1.0
    box = object_box(m)            # tiles cropped to the object: more of it per pixel
    sl = (slice(None),) + box
    imgs, bad, m = imgs[sl], bad[sl] & m[box], m[box]
    truth = None if truth is None else np.asarray(truth, bool)[sl] & m
    ncols = max(1, min(int(np.ceil(np.sqrt(k * 1.6))), k))
    h, w = m.shape
    s = min(1.0, (max_width - 4 * (ncols - 1)) / (ncols * w))
    size = (max(1, int(w * s)), max(1, int(h * s)))

    def shrink(a):
        a = np.ascontiguousarray(a, dtype=np.float32)
        return a if s >= 1.0 else cv2.resize(a, size, interpolation=cv2.INTER_AREA)

    mm = shrink(m) >= 0.5
    tiles = []
    for i in range(k):
        g = np.repeat(_u8(np.where(mm, shrink(imgs[i]) / (top or 1.0), 0) * 0.85)[..., None],
                      3, -1)
        f = shrink(bad[i]) >= 0.5
        if truth is None:
            g[f] = (230, 30, 30)
        else:
            t = shrink(truth[i]) >= 0.5
            g[f & t] = (0, 200, 0)
            g[f & ~t] = (40, 90, 255)
            g[~f & t] = (230, 30, 30)
        tiles.append(g)
    pic = montage(tiles, ncols=ncols, labels=[f"{i + 1}" for i in range(k)],
                  max_width=max_width)
    if truth is None:
        note = f"red: observation excluded by the mask ({100 * (1 - used):.1f} % excluded)"
    else:
        note = ("green: excluded, truly highlight/shadow   blue: excluded, clean   "
                f"red: used, truly highlight/shadow ({100 * (1 - used):.1f} % excluded)")
    return _below(pic, note)


def weights_picture(weights, object_mask=None, *, title="weights", vmax=None,
                    labels=None, max_width=1200):
    """(n, H, W) weights in viridis over [0, vmax] (default the 99th percentile over the
    object) with a colour bar, one tile per image or ring; ``labels`` titles the tiles
    (default 1..n, e.g. the rings' zeniths)."""
    w = np.asarray(weights, dtype=np.float32)
    m = np.ones(w.shape[1:], bool) if object_mask is None else np.asarray(object_mask, bool)
    if vmax is None:
        vals = w[:, m]
        vmax = float(np.percentile(vals, 99.0)) if vals.size else 1.0
        vmax = vmax if vmax > 0 else 1.0
    box = object_box(m)
    tiles = [colorize(x[box], 0.0, vmax, cmap="viridis", valid=m[box]) for x in w]
    labels = [f"{i + 1}" for i in range(len(tiles))] if labels is None else list(labels)
    grid = montage(tiles, labels=labels, max_width=max_width)
    bar = color_bar(min(grid.shape[0], 360), 0.0, vmax, cmap="viridis", label=title)
    return hstack(grid, bar)


def _below(pic, note, size=14):
    tw, th = text_size(note, size)
    w = max(pic.shape[1], tw + 12)
    out = _canvas(pic.shape[0] + th + 14, w)
    out[:pic.shape[0], :pic.shape[1]] = pic
    return _draw(out, [(6, pic.shape[0] + 6, note, size, "la")])
