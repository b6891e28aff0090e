"""Rig calibration (thesis Chapter 6): pure functions, a calibration file, a CLI.

Steps (each a pure function on numpy arrays; ``psbench-calibrate <step>`` runs it
on capture folders and stores the result in a calibration folder):

``dark``        Dark-frame hot pixels (6.5.3): pixels of the dark frame (all LEDs
                off) above a threshold are hot; in every image they are replaced by
                the median of their 3x3 neighbourhood (``cv2.medianBlur``).
``response``    Camera response (6.5.2): mean values of the 9 patches of a gray chart
                with known linear radiances are fitted by a 6th-order polynomial
                g(measured) = radiance (the *inverse* response, anchored at g(0) = 0);
                applying g linearises images. g is applied through a table made
                monotone by a running maximum; a fit that dips by more than 0.5 % of
                its range on [0, 1] is refused and the degree lowered (warning).
``directions``  Light directions (6.3): in each image of a specular sphere the
                highlight centroid (intensity-weighted, pixels above ``fraction`` of
                the sphere's maximum) gives the sphere normal n there; with the
                camera vector v = (0, 0, 1) the light direction is the mirror
                reflection l = 2 (n.v) n - v. Sphere centre and radius come from its
                mask (centroid, sqrt(area / pi)) or are given. With the LED
                distance from the sphere centre (measured, pixel units) the light
                *positions* follow: P = p + t l with p the highlight point and
                |P - C| = distance; the direction then used for PS is P / |P|
                (from the image centre).
``nearlight``   Near-light correction (6.5.4): a white plane is rendered with the
                measured light positions (:func:`psbench.render` with
                ``light_positions`` and inverse-square ``falloff``); each image is
                divided by its rendered plane normalised at the image centre. This
                removes the intensity fall-off across the field (1/d^2 and the
                changing angle of incidence); the per-pixel change of *direction*
                on non-planar surfaces remains.
``flat``        Flat field (6.5.1): a white image (a stack is averaged; near-light
                fields divided out when known) is fitted by a 2-D polynomial of
                configurable degree (least squares over monomials x^i y^j, i + j <=
                degree, normalised coordinates); images are divided by the fit,
                which is normalised to 1 at the image centre.
``powers``      Light powers (6.4): mean intensity of the white target under each
                LED (after dark, response, flat and near-light) divided by the
                target's foreshortening. The thesis writes "scaling with the solid
                angle ... sin(Z_source)"; for a horizontal Lambertian target the
                irradiance from a source of power mu at zenith Z is mu cos(Z) =
                mu sin(90 deg - Z): the thesis's Z there is the source *elevation*
                above the target plane, so psbench divides by cos(zenith) (the
                sine of the elevation). Powers are normalised to mean 1.
``pixelsize``   Geometric scale (6.6): the period (pixels) of a grid target of known
                pitch is found from the peak of the Fourier spectrum of its row and
                column mean profiles (Hann window, 16x zero padding, parabolic peak
                interpolation); pixel size = pitch / period.

:func:`apply_calibration` applies a :class:`Calibration` in the order
dark -> response -> flat / near light -> powers. :func:`psbench.io.read_dataset`
applies a folder's saved calibration automatically.

Calibration folder: ``calibration.json`` (steps, parameters, response coefficients,
pixel size, provenance) plus ``directions.npy``, ``positions.npy``, ``powers.npy``,
``flat.npy``, ``hot.npy`` as present; written atomically (temp dir + rename).
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._checks import PsbenchError, as_images

__all__ = ["Calibration", "sphere_geometry", "light_directions_from_sphere", "light_positions",
           "hot_pixels", "remove_hot_pixels", "chart_means", "fit_response", "apply_response",
           "polyfit2d", "polyval2d", "flat_field", "near_light_fields", "light_powers",
           "pixel_size", "grid_period", "apply_calibration", "save_calibration",
           "load_calibration", "calibrate_folder", "main"]


# --------------------------------------------------------------------------- dark
def hot_pixels(dark, threshold=None):
    """Hot pixels of a dark frame.

    Parameters
    ----------
    dark : (H, W) float
        Dark frame (all lights off), in [0, 1].
    threshold : float, optional
        Absolute threshold. Default: ``median + 8 * sigma`` of the frame with sigma
        estimated from the 1st-99th percentile range of the pixels (robust to the
        hot pixels themselves), and at least 0.05 above the median.

    Returns
    -------
    hot : (H, W) bool
    threshold : float
    """
    d = np.asarray(dark, dtype=np.float32)
    if d.ndim != 2:
        raise PsbenchError(f"dark must have shape (H, W), got {d.shape}")
    if threshold is None:
        med = float(np.median(d))
        lo, hi = np.percentile(d, [1, 99])
        core = d[(d >= lo) & (d <= hi)]
        sigma = float(core.std()) if core.size else 0.0
        threshold = med + max(8.0 * sigma, 0.05)
    return d > threshold, float(threshold)


def remove_hot_pixels(images, hot, ksize=3):
    """Replace ``hot`` pixels in every image by the median of their neighbourhood.

    Parameters
    ----------
    images : (k, H, W) float32
    hot : (H, W) bool
    ksize : {3, 5}
        ``cv2.medianBlur`` aperture (float32 images allow 3 and 5).

    Returns
    -------
    (k, H, W) float32 (a copy)
    """
    import cv2
    imgs = as_images(images)
    hot = np.asarray(hot, bool)
    if hot.shape != imgs.shape[1:]:
        raise PsbenchError(f"hot must have shape {imgs.shape[1:]}, got {hot.shape}")
    if ksize not in (3, 5):
        raise PsbenchError(f"ksize must be 3 or 5, got {ksize}")
    out = imgs.copy()
    if not hot.any():
        return out
    for i in range(out.shape[0]):
        med = cv2.medianBlur(imgs[i], ksize)
        out[i][hot] = med[hot]
    return out


# --------------------------------------------------------------------------- response
def chart_means(image, boxes, *, inner=0.6):
    """Mean of each chart patch.

    Parameters
    ----------
    image : (H, W) float
    boxes : sequence of (r0, r1, c0, c1)
        Patch boxes (rows r0:r1, cols c0:c1).
    inner : float
        Fraction of each box (centred) averaged, to stay clear of patch edges.
    """
    img = np.asarray(image, dtype=np.float64)
    out = []
    for (r0, r1, c0, c1) in boxes:
        h, w = r1 - r0, c1 - c0
        dr, dc = int(round(h * (1 - inner) / 2)), int(round(w * (1 - inner) / 2))
        patch = img[r0 + dr:r1 - dr, c0 + dc:c1 - dc]
        if patch.size == 0:
            raise PsbenchError(f"chart box {(r0, r1, c0, c1)} is empty inside the image {img.shape}")
        out.append(patch.mean())
    return np.array(out)


def _monotone_lut(coeffs, n=4097):
    grid = np.linspace(0.0, 1.0, n)
    v = np.maximum.accumulate(np.polyval(np.asarray(coeffs, dtype=np.float64), grid))
    return grid, v


def fit_response(measured, radiance, degree=6, *, anchor=True, max_dip=0.005):
    """Fit the inverse camera response g(measured) = radiance by a polynomial.

    Parameters
    ----------
    measured : (n,) float
        Mean image values of the chart patches, in [0, 1].
    radiance : (n,) float
        Their known linear radiances (any common scale).
    degree : int
        Polynomial degree (6 in the thesis).
    anchor : bool
        Add the point (0, 0) (black stays black) to the fit.
    max_dip : float
        Monotonicity check: the polynomial may dip below its running maximum on
        [0, 1] by at most this fraction of its range (such tiny dips occur near 0,
        where the inverse of a gamma curve is flat, and are removed by the running
        maximum in :func:`apply_response`); otherwise the degree is lowered until
        it holds, with a :class:`UserWarning`.

    Returns
    -------
    coeffs : (degree+1,) float64
        Highest power first (``np.polyval`` order).
    """
    m = np.asarray(measured, dtype=np.float64).ravel()
    r = np.asarray(radiance, dtype=np.float64).ravel()
    if m.shape != r.shape or m.size < 2:
        raise PsbenchError(f"measured and radiance must be equal-length vectors (n >= 2), "
                           f"got {m.shape} and {r.shape}")
    if anchor:
        m, r = np.concatenate([[0.0], m]), np.concatenate([[0.0], r])
    if np.any(np.diff(r[np.argsort(m)]) < 0):
        raise PsbenchError("the chart's measured values are not in the order of its radiances "
                           "(check patch boxes / radiance order)")
    deg0 = int(degree)
    grid = np.linspace(0, 1, 1025)
    for deg in range(min(deg0, m.size - 1), 0, -1):
        c = np.polyfit(m, r, deg)
        v = np.polyval(c, grid)
        span = v.max() - v.min()
        dip = (np.maximum.accumulate(v) - v).max() / span if span > 0 else np.inf
        if span > 0 and dip <= max_dip and v[-1] > v[0]:
            if deg != deg0:
                warnings.warn(f"response fit of degree {deg0} is not monotone on [0, 1]; "
                              f"using degree {deg}", UserWarning, stacklevel=2)
            return c
    raise PsbenchError("no monotone response fit found; check the chart image")


def apply_response(images, coeffs):
    """Linearise images with the inverse response polynomial.

    The polynomial is tabulated on [0, 1] (4097 samples), made monotone by a running
    maximum and clipped at 0, then applied by linear interpolation.
    """
    grid, lut = _monotone_lut(coeffs)
    a = np.asarray(images, dtype=np.float64)
    out = np.interp(a, grid, np.maximum(lut, 0.0))
    return out.astype(np.float32)


# --------------------------------------------------------------------------- flat field
def _norm_coords(shape):
    H, W = shape
    u = (np.arange(W) - (W - 1) / 2) / max((W - 1) / 2, 1)
    v = ((H - 1) / 2 - np.arange(H)) / max((H - 1) / 2, 1)
    return u, v


def _monomials(degree):
    return [(i, j) for i in range(degree + 1) for j in range(degree + 1 - i)]


def polyfit2d(image, degree=4, mask=None, *, max_samples=40000):
    """Least-squares 2-D polynomial fit of an image.

    Parameters
    ----------
    image : (H, W) float
    degree : int
        Total degree (monomials u^i v^j, i + j <= degree, u, v in [-1, 1]).
    mask : (H, W) bool, optional
        Pixels used in the fit.
    max_samples : int
        Pixels are subsampled on a regular stride above this count.

    Returns
    -------
    coeffs : (n_terms,) float64 (order of ``_monomials(degree)``)
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2:
        raise PsbenchError(f"image must have shape (H, W), got {img.shape}")
    if not 0 <= int(degree) <= 12:
        raise PsbenchError(f"degree must be in 0..12, got {degree}")
    u, v = _norm_coords(img.shape)
    U, V = np.meshgrid(u, v)
    sel = np.ones(img.shape, bool) if mask is None else np.asarray(mask, bool)
    idx = np.flatnonzero(sel.ravel())
    if idx.size < len(_monomials(degree)):
        raise PsbenchError("too few pixels for the polynomial fit")
    step = max(1, idx.size // max_samples)
    idx = idx[::step]
    A = np.stack([U.ravel()[idx] ** i * V.ravel()[idx] ** j for i, j in _monomials(degree)], 1)
    c, *_ = np.linalg.lstsq(A, img.ravel()[idx], rcond=None)
    return c


def polyval2d(coeffs, shape, degree):
    """Evaluate :func:`polyfit2d` coefficients on an (H, W) grid."""
    u, v = _norm_coords(shape)
    out = np.zeros(shape)
    for c, (i, j) in zip(coeffs, _monomials(degree)):
        out += c * (v[:, None] ** j) * (u[None, :] ** i)
    return out


def flat_field(white, degree=4, *, mask=None, near=None):
    """Flat-field (illumination distribution) from white-target images.

    Parameters
    ----------
    white : (H, W) or (k, H, W) float
        Linear white-target image(s); a stack is averaged (after dividing by
        ``near`` when given).
    degree : int
        Polynomial degree (thesis 6.5.1: "2 dimensional polynomial").
    near : (k, H, W) float, optional
        Near-light fields to divide out first (:func:`near_light_fields`).

    Returns
    -------
    flat : (H, W) float32
        The fitted field normalised to 1 at the image centre; divide images by it.
    """
    w = np.asarray(white, dtype=np.float64)
    if w.ndim == 2:
        w = w[None]
    if w.ndim != 3:
        raise PsbenchError(f"white must have shape (H, W) or (k, H, W), got {w.shape}")
    if near is not None:
        near = np.asarray(near, dtype=np.float64)
        if near.shape != w.shape:
            raise PsbenchError(f"near must have shape {w.shape}, got {near.shape}")
        w = w / near
    mean = w.mean(axis=0)
    c = polyfit2d(mean, degree, mask)
    f = polyval2d(c, mean.shape, degree)
    centre = polyval2d(c, (1, 1), degree)[0, 0]  # u = v = 0
    if centre <= 0:
        raise PsbenchError("flat field fit is not positive at the image centre; bad white image?")
    f = f / centre
    if (f <= 0.05).any():
        raise PsbenchError("flat field fit drops below 5 % of the centre; bad white image or degree")
    return f.astype(np.float32)


# --------------------------------------------------------------------------- geometry
def sphere_geometry(mask):
    """Centre (x, y) in psbench's frame and radius (pixels) of a sphere from its mask."""
    m = np.asarray(mask, bool)
    if m.ndim != 2 or not m.any():
        raise PsbenchError("sphere mask must be a non-empty (H, W) bool array")
    H, W = m.shape
    r, c = np.nonzero(m)
    cx = c.mean() - (W - 1) / 2
    cy = (H - 1) / 2 - r.mean()
    return float(cx), float(cy), float(np.sqrt(m.sum() / np.pi))


def light_directions_from_sphere(images, mask=None, *, center=None, radius=None, fraction=0.8):
    """Light directions from images of a specular sphere (Section 6.3).

    Parameters
    ----------
    images : (k, H, W) float
        One image per light.
    mask : (H, W) bool, optional
        The sphere's silhouette (centre and radius are taken from it).
    center : (x, y), optional
        Sphere centre in psbench's frame (pixels), overrides the mask's.
    radius : float, optional
    fraction : float
        Highlight pixels are those above ``fraction`` x the image's maximum on the
        sphere; the centroid is weighted by (I - threshold).

    Returns
    -------
    directions : (k, 3) float64
        Unit vectors l = 2 (n.v) n - v.
    normals : (k, 3) float64
        Sphere normals at the highlights.
    points : (k, 2) float64
        Highlight centroids (x, y) in psbench's frame.
    """
    imgs = as_images(images)
    k, H, W = imgs.shape
    if mask is None and (center is None or radius is None):
        raise PsbenchError("give the sphere mask or both center and radius")
    if mask is not None:
        mcx, mcy, mr = sphere_geometry(mask)
    cx, cy = center if center is not None else (mcx, mcy)
    R = float(radius if radius is not None else mr)
    x = np.arange(W) - (W - 1) / 2
    y = (H - 1) / 2 - np.arange(H)
    X, Y = np.meshgrid(x, y)
    inside = (X - cx) ** 2 + (Y - cy) ** 2 < R * R
    if mask is not None:
        inside &= np.asarray(mask, bool)
    dirs, nrm, pts = np.zeros((k, 3)), np.zeros((k, 3)), np.zeros((k, 2))
    for i in range(k):
        img = np.where(inside, imgs[i], 0.0)
        top = float(img.max())
        if top <= 0:
            raise PsbenchError(f"sphere image {i + 1}: no light on the sphere (all zero)")
        thr = fraction * top
        w = np.clip(img - thr, 0, None)
        s = w.sum()
        px, py = float((w * X).sum() / s), float((w * Y).sum() / s)
        nx, ny = (px - cx) / R, (py - cy) / R
        rr = nx * nx + ny * ny
        if rr >= 1:
            raise PsbenchError(f"sphere image {i + 1}: highlight at the silhouette; light behind the sphere?")
        n = np.array([nx, ny, np.sqrt(1 - rr)])
        l = 2 * n[2] * n - np.array([0.0, 0.0, 1.0])
        dirs[i], nrm[i], pts[i] = l / np.linalg.norm(l), n, (px, py)
    if (dirs[:, 2] <= 0).any():
        bad = np.flatnonzero(dirs[:, 2] <= 0) + 1
        raise PsbenchError(f"sphere images {bad.tolist()}: light directions below the horizon")
    return dirs, nrm, pts


def light_positions(directions, normals, distance, *, center, radius, center_z=0.0):
    """Light positions from sphere highlights and the measured LED distance.

    The light lies on the ray from the highlight point p = C + R n along l; the
    point at ``distance`` from the sphere centre C is taken.

    Parameters
    ----------
    directions, normals : (k, 3)
        From :func:`light_directions_from_sphere`.
    distance : float or (k,)
        LED distance from the sphere centre (pixel units).
    center : (x, y)
        Sphere centre in psbench's frame; ``center_z`` its height.
    radius : float

    Returns
    -------
    positions : (k, 3) float64 (pixel units, origin at the image centre on the datum)
    """
    l = np.asarray(directions, float)
    n = np.asarray(normals, float)
    C = np.array([center[0], center[1], center_z], float)
    p = C + radius * n
    q = p - C
    dist = np.broadcast_to(np.asarray(distance, float), (l.shape[0],))
    # |q + t l| = D, t >= 0:  t = -q.l + sqrt((q.l)^2 - |q|^2 + D^2)
    ql = (q * l).sum(1)
    disc = ql ** 2 - (q * q).sum(1) + dist ** 2
    if (disc < 0).any() or (dist <= radius).any():
        raise PsbenchError("distance must exceed the sphere radius")
    t = -ql + np.sqrt(disc)
    return p + t[:, None] * l


def near_light_fields(shape, positions):
    """Rendered white planes for near lights, normalised to 1 at the image centre.

    Parameters
    ----------
    shape : (H, W)
    positions : (k, 3) float
        Light positions (pixel units, origin at the image centre on the datum).

    Returns
    -------
    (k, H, W) float32
        Plane image i (Lambert, inverse-square falloff) / its value at the origin.
    """
    from .render import render
    from .surfaces import surface_from_height

    P = np.asarray(positions, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise PsbenchError(f"positions must have shape (k, 3), got {P.shape}")
    H, W = shape
    plane = surface_from_height(np.zeros((H, W)))
    d = P / np.linalg.norm(P, axis=1)[:, None]
    sc = render(plane, d, model="lambert", light_positions=P, falloff=True, shadows=False)
    # render's falloff is 1 at the origin, where the plane's shading is cos(zenith)
    return (sc.images / d[:, 2].astype(np.float32)[:, None, None]).astype(np.float32)


def light_powers(white, directions, *, flat=None, near=None, mask=None):
    """Relative light powers from white-target images (Section 6.4).

    Parameters
    ----------
    white : (k, H, W) float
        Linear white-target images, one per light (dark and response corrected).
    directions : (k, 3)
        Light directions (zenith Z_i = arccos d_z).
    flat : (H, W), optional
    near : (k, H, W), optional
        Divided out before averaging.
    mask : (H, W) bool, optional
        Pixels averaged.

    Returns
    -------
    powers : (k,) float64, mean 1
        mean(W_i) / cos(Z_i), i.e. divided by sin(elevation) -- the thesis's sin(Z)
        with Z measured from the target plane (see module docstring).
    """
    w = as_images(white, "white")
    d = np.asarray(directions, float)
    if d.shape != (w.shape[0], 3):
        raise PsbenchError(f"directions must have shape ({w.shape[0]}, 3), got {d.shape}")
    w = w.astype(np.float64)
    if flat is not None:
        w = w / np.asarray(flat, np.float64)
    if near is not None:
        w = w / np.asarray(near, np.float64)
    m = np.ones(w.shape[1:], bool) if mask is None else np.asarray(mask, bool)
    means = w[:, m].mean(axis=1)
    p = means / d[:, 2]
    if (p <= 0).any():
        raise PsbenchError("white-target image(s) are black; cannot estimate light powers")
    return p / p.mean()


def grid_period(image, *, min_period=2.5):
    """Period in pixels of a grid pattern along x and y (Fourier peak of profiles).

    Returns
    -------
    (period_x, period_y) floats
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim != 2:
        raise PsbenchError(f"image must have shape (H, W), got {img.shape}")
    out = []
    for prof in (img.mean(axis=0), img.mean(axis=1)):
        n = prof.size
        p = (prof - prof.mean()) * np.hanning(n)
        pad = 16 * n
        spec = np.abs(np.fft.rfft(p, pad))
        f = np.fft.rfftfreq(pad)
        ok = (f > 1.5 / n) & (f < 1.0 / min_period)
        if not ok.any():
            raise PsbenchError("image too small for a grid period estimate")
        i = np.flatnonzero(ok)[np.argmax(spec[ok])]
        if 0 < i < spec.size - 1:
            a, b, c = np.log(spec[i - 1:i + 2] + 1e-30)
            off = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
        else:
            off = 0.0
        out.append(1.0 / ((i + off) / pad))
    return float(out[0]), float(out[1])


def pixel_size(image, pitch):
    """Pixel size (units of ``pitch`` per pixel) from an image of a grid of known pitch."""
    px, py = grid_period(image)
    return float(pitch) / (0.5 * (px + py))


# --------------------------------------------------------------------------- calibration
@dataclass
class Calibration:
    """Calibration results; any field may be None (step not done).

    Attributes
    ----------
    directions : (k, 3) or None
    positions : (k, 3) or None
        Light positions (pixel units); enable the near-light correction.
    powers : (k,) or None
    flat : (H, W) float32 or None
    flat_degree : int
    response : (d+1,) or None
        Inverse response polynomial (np.polyval order).
    hot : (H, W) bool or None
    hot_threshold : float or None
    pixel_size : float or None
        Millimetres per pixel.
    near_light : bool
        Apply the near-light correction when positions are known.
    meta : dict
    """

    directions: np.ndarray | None = None
    positions: np.ndarray | None = None
    powers: np.ndarray | None = None
    flat: np.ndarray | None = None
    flat_degree: int = 4
    response: np.ndarray | None = None
    hot: np.ndarray | None = None
    hot_threshold: float | None = None
    pixel_size: float | None = None
    near_light: bool = True
    meta: dict = field(default_factory=dict)

    def steps(self):
        s = []
        if self.hot is not None or self.hot_threshold is not None:
            s.append("dark")
        if self.response is not None:
            s.append("response")
        if self.directions is not None:
            s.append("directions")
        if self.positions is not None and self.near_light:
            s.append("nearlight")
        if self.flat is not None:
            s.append("flat")
        if self.powers is not None:
            s.append("powers")
        if self.pixel_size is not None:
            s.append("pixelsize")
        return s


def apply_calibration(images, calib, *, dark=None, steps=None):
    """Apply a calibration: dark -> response -> flat / near light -> powers.

    Parameters
    ----------
    images : (k, H, W) float
        Raw images in [0, 1].
    calib : Calibration
    dark : (H, W) float, optional
        A dark frame taken with these images; its hot pixels (at the calibration's
        threshold) are added to the calibration's.
    steps : iterable of str, optional
        Restrict to these steps (``dark, response, flat, nearlight, powers``).

    Returns
    -------
    (k, H, W) float32
    """
    imgs = as_images(images)
    k, H, W = imgs.shape
    want = set(calib.steps() if steps is None else steps)
    if "dark" in want:
        hot = None if calib.hot is None else np.asarray(calib.hot, bool)
        if dark is not None:
            dh, _ = hot_pixels(dark, calib.hot_threshold)
            hot = dh if hot is None else (hot | dh)
        if hot is not None:
            if hot.shape != (H, W):
                raise PsbenchError(f"calibration hot-pixel map is {hot.shape}, images are {(H, W)}")
            imgs = remove_hot_pixels(imgs, hot)
    if "response" in want and calib.response is not None:
        imgs = apply_response(imgs, calib.response)
    if "flat" in want and calib.flat is not None:
        if calib.flat.shape != (H, W):
            raise PsbenchError(f"calibration flat field is {calib.flat.shape}, images are {(H, W)}")
        imgs = imgs / calib.flat[None].astype(np.float32)
    if "nearlight" in want and calib.positions is not None and calib.near_light:
        if calib.positions.shape[0] != k:
            raise PsbenchError(f"calibration has {calib.positions.shape[0]} light positions for {k} images")
        imgs = imgs / near_light_fields((H, W), calib.positions)
    if "powers" in want and calib.powers is not None:
        if calib.powers.shape != (k,):
            raise PsbenchError(f"calibration has {calib.powers.shape[0]} light powers for {k} images")
        imgs = imgs / calib.powers.astype(np.float32)[:, None, None]
    return np.ascontiguousarray(imgs, dtype=np.float32)


_ARRAYS = ("directions", "positions", "powers", "flat", "hot")


def save_calibration(calib, path, *, overwrite=True):
    """Write ``calibration.json`` + ``.npy`` arrays into the folder ``path`` atomically."""
    from .io import _json_default, atomic_dir

    doc = {"format": "psbench-calibration", "version": 1, "steps": calib.steps(),
           "flat_degree": int(calib.flat_degree), "near_light": bool(calib.near_light),
           "response": None if calib.response is None else [float(c) for c in calib.response],
           "hot_threshold": calib.hot_threshold, "pixel_size_mm": calib.pixel_size,
           "meta": calib.meta, "arrays": {}}
    with atomic_dir(path, overwrite=overwrite) as tmp:
        for name in _ARRAYS:
            a = getattr(calib, name)
            if a is not None:
                np.save(tmp / f"{name}.npy", np.asarray(a))
                doc["arrays"][name] = f"{name}.npy"
        if calib.directions is not None:
            doc["directions"] = np.asarray(calib.directions).tolist()
        if calib.powers is not None:
            doc["powers"] = np.asarray(calib.powers).tolist()
        (tmp / "calibration.json").write_text(json.dumps(doc, indent=1, default=_json_default))
    return Path(path)


def load_calibration(path):
    """Read a calibration folder (or its ``calibration.json``)."""
    p = Path(path)
    folder = p.parent if p.is_file() else p
    jf = p if p.is_file() else p / "calibration.json"
    if not jf.is_file():
        raise PsbenchError(f"calibration {str(p)!r}: no calibration.json")
    try:
        doc = json.loads(jf.read_text())
    except json.JSONDecodeError as e:
        raise PsbenchError(f"{jf}: invalid JSON ({e})") from None
    if doc.get("format") != "psbench-calibration":
        raise PsbenchError(f"{jf}: not a psbench calibration file")
    kw = {}
    for name, fn in doc.get("arrays", {}).items():
        f = folder / fn
        if not f.is_file():
            raise PsbenchError(f"calibration {jf}: array file {fn} is missing")
        kw[name] = np.load(f)
    if kw.get("hot") is not None:
        kw["hot"] = kw["hot"].astype(bool)
    resp = doc.get("response")
    return Calibration(response=None if resp is None else np.array(resp, float),
                       flat_degree=int(doc.get("flat_degree", 4)),
                       near_light=bool(doc.get("near_light", True)),
                       hot_threshold=doc.get("hot_threshold"),
                       pixel_size=doc.get("pixel_size_mm"), meta=doc.get("meta", {}), **kw)


# --------------------------------------------------------------------------- folders
def _read_folder_images(folder):
    from .io import read_dataset
    ds = read_dataset(folder, calibration="none")
    dark = None
    dp = Path(folder) / "dark.png"
    if dp.is_file():
        from .io import read_image
        dark = read_image(dp, bits=ds.meta.get("bits") if ds.meta.get("bits") != 8 else None)
    return ds, dark


def _single(folder):
    from .io import read_image
    folder = Path(folder)
    meta = {}
    if (folder / "psbench.json").is_file():
        meta = json.loads((folder / "psbench.json").read_text())
    imgs = sorted(folder.glob("[0-9]*.png"))
    if folder.is_file():
        return read_image(folder), meta
    if not imgs:
        raise PsbenchError(f"{folder}: no image")
    return read_image(imgs[0]), meta


def step_dark(calib, dark, threshold=None):
    hot, thr = hot_pixels(dark, threshold)
    calib.hot, calib.hot_threshold = hot, thr
    calib.meta["dark"] = {"hot_pixels": int(hot.sum()), "threshold": thr}
    return calib


def step_response(calib, chart_folder, degree=6):
    img, meta = _single(chart_folder)
    if "boxes" not in meta or "radiance" not in meta:
        raise PsbenchError(f"{chart_folder}: psbench.json must list chart 'boxes' and 'radiance'")
    img = apply_calibration(img[None], calib, steps=["dark"])[0]
    m = chart_means(img, meta["boxes"])
    calib.response = fit_response(m, meta["radiance"], degree)
    calib.meta["response"] = {"degree": int(calib.response.size - 1), "measured": m.tolist(),
                              "radiance": list(meta["radiance"])}
    return calib


def step_directions(calib, sphere_folder, *, distance=None, fraction=0.8, center=None,
                    radius=None):
    ds, dark = _read_folder_images(sphere_folder)
    imgs = apply_calibration(ds.images, calib, dark=dark, steps=["dark", "response"])
    has_mask = (Path(sphere_folder) / "mask.png").is_file()
    if not has_mask and (center is None or radius is None):
        raise PsbenchError(f"{sphere_folder}: no mask.png; give the sphere --center X Y and --radius R")
    mask = ds.mask if has_mask else None
    d, n, pts = light_directions_from_sphere(imgs, mask, center=center, radius=radius,
                                             fraction=fraction)
    calib.directions = d
    if has_mask:
        cx, cy, R = sphere_geometry(ds.mask)
    if center is not None:
        cx, cy = center
    if radius is not None:
        R = float(radius)
    if distance is None:
        distance = ds.meta.get("distance_px")
    calib.meta["sphere"] = {"center": [cx, cy], "radius": R, "distance_px": distance}
    if distance is not None:
        P = light_positions(d, n, float(distance), center=(cx, cy), radius=R)
        calib.positions = P
        calib.directions = P / np.linalg.norm(P, axis=1)[:, None]
    return calib


def step_white(calib, white_folder, *, degree=4, flat=True, powers=True):
    ds, dark = _read_folder_images(white_folder)
    imgs = apply_calibration(ds.images, calib, dark=dark, steps=["dark", "response"])
    near = None
    if calib.positions is not None and calib.near_light:
        near = near_light_fields(imgs.shape[1:], calib.positions)
    if flat:
        calib.flat = flat_field(imgs, degree, near=near)
        calib.flat_degree = int(degree)
    if powers:
        dirs = calib.directions if calib.directions is not None else ds.lights.directions
        calib.powers = light_powers(imgs, dirs, flat=calib.flat, near=near)
    return calib


def step_pixelsize(calib, grid_folder, pitch=None):
    img, meta = _single(grid_folder)
    pitch = meta.get("pitch_mm") if pitch is None else pitch
    if pitch is None:
        raise PsbenchError(f"{grid_folder}: give the grid pitch (mm) with --pitch")
    img = apply_calibration(img[None], calib, steps=["dark", "response"])[0]
    calib.pixel_size = pixel_size(img, float(pitch))
    return calib


def calibrate_folder(capture, out=None, *, raw=None, distance=None, flat_degree=4,
                     response_degree=6, threshold=None, near_light=True):
    """Run every step on a capture folder with ``calibration_raw/`` targets.

    Parameters
    ----------
    capture : folder of the object capture (its ``dark.png`` is the dark frame)
    out : calibration folder (default ``<capture>/calibration``)
    raw : folder with ``sphere/ white/ chart/ grid/`` (default ``<capture>/calibration_raw``)

    Returns
    -------
    Calibration
    """
    from .io import read_image
    cap = Path(capture)
    raw = cap / "calibration_raw" if raw is None else Path(raw)
    out = cap / "calibration" if out is None else Path(out)
    calib = Calibration(near_light=near_light)
    dp = cap / "dark.png"
    if dp.is_file():
        step_dark(calib, read_image(dp), threshold)
    if (raw / "chart").is_dir():
        step_response(calib, raw / "chart", response_degree)
    if (raw / "sphere").is_dir():
        step_directions(calib, raw / "sphere", distance=distance)
    if (raw / "white").is_dir():
        step_white(calib, raw / "white", degree=flat_degree)
    if (raw / "grid").is_dir():
        step_pixelsize(calib, raw / "grid")
    calib.meta["source"] = str(cap)
    save_calibration(calib, out)
    return calib


# --------------------------------------------------------------------------- CLI
def _load_or_new(path):
    p = Path(path)
    return load_calibration(p) if (p / "calibration.json").is_file() else Calibration()


def main(argv=None):
    """``psbench-calibrate <step> ...``; see ``psbench-calibrate -h``."""
    ap = argparse.ArgumentParser(
        prog="psbench-calibrate",
        description="Calibrate a photometric-stereo rig (thesis Chapter 6). Each step reads "
                    "target captures and updates a calibration folder (calibration.json + .npy), "
                    "which psbench.io.read_dataset applies automatically when it sits in a "
                    "capture folder as calibration/.")
    sub = ap.add_subparsers(dest="step", required=True)
    a = sub.add_parser("all", help="every step from <capture>/calibration_raw/{sphere,white,chart,grid}")
    a.add_argument("capture")
    a.add_argument("--out")
    a.add_argument("--distance", type=float, help="LED distance from the sphere centre (pixels)")
    a.add_argument("--flat-degree", type=int, default=4)
    a.add_argument("--response-degree", type=int, default=6)
    a.add_argument("--threshold", type=float)
    a.add_argument("--no-near-light", action="store_true")
    for name, hlp in (("dark", "hot pixels from a dark frame (PNG or folder with dark.png)"),
                      ("response", "inverse response from a gray-chart folder"),
                      ("directions", "light directions (and positions) from a specular-sphere folder"),
                      ("flat", "flat field from a white-target folder"),
                      ("powers", "light powers from a white-target folder"),
                      ("pixelsize", "pixel size from a grid-target folder")):
        p = sub.add_parser(name, help=hlp)
        p.add_argument("input")
        p.add_argument("--out", required=True, help="calibration folder to create/update")
        if name == "dark":
            p.add_argument("--threshold", type=float)
        if name == "response":
            p.add_argument("--degree", type=int, default=6)
        if name == "directions":
            p.add_argument("--distance", type=float,
                           help="LED distance from the sphere centre in pixels (enables near light)")
            p.add_argument("--fraction", type=float, default=0.8)
            p.add_argument("--center", type=float, nargs=2, metavar=("X", "Y"),
                           help="sphere centre in psbench's frame (pixels from the image centre, y up)")
            p.add_argument("--radius", type=float, help="sphere radius in pixels")
        if name == "flat":
            p.add_argument("--degree", type=int, default=4)
        if name == "pixelsize":
            p.add_argument("--pitch", type=float, help="grid pitch in mm")
    s = sub.add_parser("show", help="print a calibration")
    s.add_argument("calibration")
    args = ap.parse_args(argv)
    try:
        if args.step == "all":
            c = calibrate_folder(args.capture, args.out, distance=args.distance,
                                 flat_degree=args.flat_degree, response_degree=args.response_degree,
                                 threshold=args.threshold, near_light=not args.no_near_light)
            print(f"calibration steps: {', '.join(c.steps())} -> "
                  f"{args.out or Path(args.capture) / 'calibration'}")
            return 0
        if args.step == "show":
            c = load_calibration(args.calibration)
            print(json.dumps({"steps": c.steps(), "pixel_size_mm": c.pixel_size,
                              "powers": None if c.powers is None else np.round(c.powers, 4).tolist(),
                              "hot_pixels": None if c.hot is None else int(c.hot.sum()),
                              "meta": c.meta}, indent=1, default=str))
            return 0
        from .io import read_image
        c = _load_or_new(args.out)
        if args.step == "dark":
            src = Path(args.input)
            step_dark(c, read_image(src / "dark.png" if src.is_dir() else src), args.threshold)
        elif args.step == "response":
            step_response(c, args.input, args.degree)
        elif args.step == "directions":
            step_directions(c, args.input, distance=args.distance, fraction=args.fraction,
                            center=args.center, radius=args.radius)
        elif args.step == "flat":
            step_white(c, args.input, degree=args.degree, powers=False)
        elif args.step == "powers":
            step_white(c, args.input, flat=False)
        elif args.step == "pixelsize":
            step_pixelsize(c, args.input, args.pitch)
        save_calibration(c, args.out)
        print(f"{args.step}: done -> {args.out} (steps: {', '.join(c.steps())})")
        return 0
    except PsbenchError as e:
        print(f"psbench-calibrate: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
