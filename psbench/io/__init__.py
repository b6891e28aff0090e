"""Image stacks, DiLiGenT-layout folders, capture and calibration folders, run outputs.

Images
------
:func:`read_images` reads 8-, 12- or 16-bit PNG/TIFF files with OpenCV
(``cv2.IMREAD_UNCHANGED``: the bit depth is never changed by the decoder) and
converts them **explicitly** to linear float32 in [0, 1] by dividing by the
largest code of the data's bit depth (8-bit -> /255, 16-bit -> /65535). OpenCV
has no 12-bit container: 12-bit sensor data is stored in 16-bit files. psbench
does **not** guess this from pixel values (a dark frame of genuine 16-bit data
can have a small maximum); pass ``bits=12`` explicitly, or record ``"bits": 12``
in a capture folder's ``psbench.json`` (``read_dataset`` then divides by 4095).
Colour images are converted to BT.601 luma ``0.299 R + 0.587 G + 0.114 B``
(alpha dropped). Float32 TIFFs are returned unchanged.

Folders (:func:`read_dataset`)
------------------------------
DiLiGenT layout::

    filenames.txt            one image file name per line (k lines)
    001.png ... 096.png      the images
    light_directions.txt     k x 3 unit vectors towards the lights (x right, y up, z to camera)
    light_intensities.txt    k x 3 (RGB) or k x 1; images are divided by it
    mask.png                 object mask (non-zero = object), optional; Dataset.object_mask
    Normal_gt.mat            optional ground truth, key ``Normal_gt`` (H, W, 3)
    normals.npy              optional ground truth as float32 (H, W, 3) (psbench writes this)

psbench capture folders add ``psbench.json`` (metadata: ``lights`` spec, ``ring``
ids, ``exposure``, ``bits``, ``current_mA``, ``calibration`` folder reference, ...)
and ``dark.png``. When the folder holds a calibration (``calibration/calibration.json``
or the folder named by ``psbench.json``'s ``calibration`` key), ``read_dataset``
applies it automatically (:func:`psbench.calibrate.apply_calibration`: dark ->
response -> flat field / near light -> powers) and takes the calibrated light
directions; ``calibration="none"`` reads the raw images. Calibration folders are
read and written by :func:`load_calibration` and :func:`save_calibration`.

Light directions are checked: a row whose norm differs from 1 by more than
``unit_tol`` (1e-3) is renormalised with a :class:`PsbenchWarning`; a row whose
norm is off by more than 10 % (or zero) is an error (the file is probably not a
direction list); rows with z < 0 (pointing away from the camera) are an error
naming the file and the 1-based rows.

Light intensities for grayscale images given as k x 3 RGB are reduced to their
BT.601 luma; for colour images each channel is divided by its own intensity
before the luma conversion.

Frame: x right, y up, z towards the camera -- DiLiGenT uses the same one (least
squares over all 96 images reproduces the published 8.41 deg / 8.39 deg on cat /
bear with no axis flip).

Topographies (:mod:`psbench.io.x3p`)
-------------------------------------
:func:`read_x3p` reads an ISO 25178-72 X3P surface file through ``x3pio`` into a
:class:`Topography` (heights in µm, ``valid``, ``pixel_size`` in µm, ``meta``);
:func:`write_x3p` writes one (increments in metres, NaN where not valid, MD5 checksums).

Writers (:func:`write_dataset`, :func:`write_outputs`, :func:`write_ply`) build their
files under temporary names and rename them into place.

Modules: ``_images`` (image files), ``_dataset`` (reading folders), ``_write``
(writing folders and outputs), ``_calibration`` (the
:class:`~psbench.calibrate.Calibration` record, applying it, calibration folders),
``x3p`` (X3P files). This package does not import
:mod:`psbench.calibrate`, which measures calibrations one layer up and re-exports the
record and its application.
"""
from __future__ import annotations

from ._calibration import load_calibration, save_calibration
from ._common import LUMA, PsbenchWarning
from ._dataset import Dataset, read_dataset, read_lights
from ._images import read_image, read_images, write_image
from ._write import atomic_dir, encode_normals, write_dataset, write_obj, write_outputs, write_ply
from .x3p import Topography, read_x3p, write_x3p

__all__ = ["Dataset", "PsbenchWarning", "read_images", "read_image", "write_image",
           "read_dataset", "write_dataset", "write_outputs", "encode_normals",
           "write_ply", "write_obj", "read_lights", "atomic_dir", "LUMA", "load_calibration",
           "save_calibration", "Topography", "read_x3p", "write_x3p"]
