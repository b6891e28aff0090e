"""The robust family: methods that use only the observations a mask expression allows
and down-weight or reject the outliers among them.

One module per method: ``trim``, ``l1``, ``sbl``, ``rpca``, ``huber``, ``cauchy``,
``tukey``, and ``choice`` -- the ``robust`` method, psbench's default robust estimator,
which this package exposes (``METHOD``, ``RobustOptions``). Shared machinery: ``_common``
(object pixels in an (n, k) layout, per-pixel WLS), ``_irls`` (reweighted least squares
with per-pixel early stopping) and the compiled ``_kernel``.
"""
from .choice import METHOD, TS_SETTINGS, RobustOptions, robust

__all__ = ["RobustOptions", "robust", "METHOD", "TS_SETTINGS"]
