"""Rig calibration (thesis Chapter 6): fitting maths, calibration-folder steps, a CLI.

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
``flat.npy``, ``hot.npy`` as present; written atomically (temp dir + rename) by
:func:`save_calibration` and read by :func:`load_calibration` (both in
:mod:`psbench.io`, re-exported here).

Layout: ``_fit`` (the fitting maths, no I/O), ``_steps`` (the folder steps:
``step_*``, :func:`calibrate_folder`) and ``_cli`` (the command: :func:`main`). The
:class:`Calibration` record, :func:`apply_calibration`, the per-image corrections and the
calibration folder live in :mod:`psbench.io` (``io._calibration``), which needs them to
read a calibrated folder; this package, one layer up, measures and re-exports them.
"""
from __future__ import annotations

from ..io._calibration import (Calibration, apply_calibration, apply_response, hot_pixels,
                               load_calibration, near_light_fields, remove_hot_pixels,
                               save_calibration)
from ._cli import main
from ._fit import (chart_means, fit_response, flat_field, grid_period, light_directions_from_sphere,
                   light_positions, light_powers, pixel_size, polyfit2d, polyval2d,
                   sphere_geometry)
from ._steps import (calibrate_folder, step_dark, step_directions, step_pixelsize, step_response,
                     step_white)

__all__ = ["Calibration", "sphere_geometry", "light_directions_from_sphere", "light_positions",
           "hot_pixels", "remove_hot_pixels", "chart_means", "fit_response", "apply_response",
           "polyfit2d", "polyval2d", "flat_field", "near_light_fields", "light_powers",
           "pixel_size", "grid_period", "apply_calibration", "save_calibration",
           "load_calibration", "calibrate_folder", "step_dark", "step_response",
           "step_directions", "step_white", "step_pixelsize", "main"]
