"""Estimators of rho * n registered as ``psbench.methods`` (one module per method)."""
