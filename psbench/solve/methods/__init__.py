"""Estimators of rho * n: one module per method, each exposing ``METHOD`` (a
:class:`psbench.registry.Method`), registered as ``psbench.methods`` entry points.

Robust methods (all compose with any mask expression: they use only the observations
in ``problem.valid``): ``robust`` (the default choice), ``trim``, ``l1``, ``sbl``,
``rpca``, ``huber``, ``cauchy``, ``tukey``; shared machinery in the private modules
``_robust_common`` (object pixels in an (n, k) layout, per-pixel WLS) and ``_irls``
(reweighted least squares with per-pixel early stopping, M-estimator options).
"""
