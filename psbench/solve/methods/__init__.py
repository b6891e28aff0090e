"""Estimators of rho * n: one module per method, each exposing ``METHOD``
(a :class:`psbench.registry.Method`), registered as ``psbench.methods`` entry points."""
