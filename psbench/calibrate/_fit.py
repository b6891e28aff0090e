"""Calibration maths (thesis Chapter 6): pure functions on numpy arrays, no file I/O.

Every measuring step of :mod:`psbench.calibrate` is one function here (see the package
docstring for the methods). The :class:`Calibration` they fill, :func:`apply_calibration`
and the corrections it applies per image (hot pixels, response, near-light fields) are
in :mod:`psbench.io._calibration`, below this package, because reading a calibrated
folder applies them; they are re-exported here.
"""
from __future__ import annotations

import warnings

import numpy as np

from .._shared.checks import PsbenchError, as_images
from .._shared.deprecation import renamed_args
from ..io._calibration import apply_response, hot_pixels, near_light_fields, remove_hot_pixels

__all__ = ["hot_pixels", "remove_hot_pixels", "chart_means", "fit_response", "apply_response",
           "polyfit2d", "polyval2d", "flat_field", "sphere_geometry",
           "light_directions_from_sphere", "light_positions", "near_light_fields",
           "light_powers", "grid_period", "pixel_size"]


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


@renamed_args(positional=("degree",))
def fit_response(measured, radiance, *, degree=6, anchor=True, max_dip=0.005):
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
                # stacklevel 3: the caller, past the renamed_args wrapper
                warnings.warn(f"response fit of degree {deg0} is not monotone on [0, 1]; "
                              f"using degree {deg} (degree= sets the first degree tried)",
                              UserWarning, stacklevel=3)
            return c
    raise PsbenchError("no monotone response fit found; check the chart image")


# --------------------------------------------------------------------------- flat field
def _norm_coords(shape):
    H, W = shape
    u = (np.arange(W) - (W - 1) / 2) / max((W - 1) / 2, 1)
    v = ((H - 1) / 2 - np.arange(H)) / max((H - 1) / 2, 1)
    return u, v


def _monomials(degree):
    return [(i, j) for i in range(degree + 1) for j in range(degree + 1 - i)]


@renamed_args(positional=("degree", "object_mask"), renamed={"mask": "object_mask"})
def polyfit2d(image, *, degree=4, object_mask=None, max_samples=40000):
    """Least-squares 2-D polynomial fit of an image.

    Parameters
    ----------
    image : (H, W) float
    degree : int
        Total degree (monomials u^i v^j, i + j <= degree, u, v in [-1, 1]).
    object_mask : (H, W) bool, optional
        Pixels used in the fit (default all).
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
    sel = np.ones(img.shape, bool) if object_mask is None else np.asarray(object_mask, bool)
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


@renamed_args(positional=("degree",), renamed={"mask": "object_mask"})
def flat_field(white, *, degree=4, object_mask=None, near=None):
    """Flat-field (illumination distribution) from white-target images.

    Parameters
    ----------
    white : (H, W) or (k, H, W) float
        Linear white-target image(s); a stack is averaged (after dividing by
        ``near`` when given).
    degree : int
        Polynomial degree (thesis 6.5.1: "2 dimensional polynomial").
    object_mask : (H, W) bool, optional
        Pixels of the white target used in the fit (default all).
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
    c = polyfit2d(mean, degree=degree, object_mask=object_mask)
    f = polyval2d(c, mean.shape, degree)
    centre = polyval2d(c, (1, 1), degree)[0, 0]  # u = v = 0
    if centre <= 0:
        raise PsbenchError("flat field fit is not positive at the image centre; bad white image?")
    f = f / centre
    if (f <= 0.05).any():
        raise PsbenchError("flat field fit drops below 5 % of the centre; bad white image or degree")
    return f.astype(np.float32)


# --------------------------------------------------------------------------- geometry
@renamed_args(renamed={"mask": "object_mask"})
def sphere_geometry(object_mask):
    """Centre (x, y) in psbench's frame and radius (pixels) of a sphere from its mask.

    Parameters
    ----------
    object_mask : (H, W) bool
        The sphere's silhouette.

    Returns
    -------
    cx, cy, radius : float
    """
    m = np.asarray(object_mask, bool)
    if m.ndim != 2 or not m.any():
        raise PsbenchError("sphere mask must be a non-empty (H, W) bool array")
    H, W = m.shape
    r, c = np.nonzero(m)
    cx = c.mean() - (W - 1) / 2
    cy = (H - 1) / 2 - r.mean()
    return float(cx), float(cy), float(np.sqrt(m.sum() / np.pi))


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def light_directions_from_sphere(images, *, object_mask=None, center=None, radius=None,
                                 fraction=0.8):
    """Light directions from images of a specular sphere (Section 6.3).

    Parameters
    ----------
    images : (k, H, W) float
        One image per light.
    object_mask : (H, W) bool, optional
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
    if object_mask is None and (center is None or radius is None):
        raise PsbenchError("give the sphere's object_mask or both center and radius")
    if object_mask is not None:
        mcx, mcy, mr = sphere_geometry(object_mask)
    cx, cy = center if center is not None else (mcx, mcy)
    R = float(radius if radius is not None else mr)
    x = np.arange(W) - (W - 1) / 2
    y = (H - 1) / 2 - np.arange(H)
    X, Y = np.meshgrid(x, y)
    inside = (X - cx) ** 2 + (Y - cy) ** 2 < R * R
    if object_mask is not None:
        inside &= np.asarray(object_mask, bool)
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


@renamed_args(renamed={"mask": "object_mask"})
def light_powers(white, directions, *, flat=None, near=None, object_mask=None):
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
    object_mask : (H, W) bool, optional
        Pixels averaged (default all).

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
    m = np.ones(w.shape[1:], bool) if object_mask is None else np.asarray(object_mask, bool)
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
