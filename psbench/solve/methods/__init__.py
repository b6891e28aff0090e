"""The methods of :func:`psbench.solve`, one module per method.

==========  ==============================================================================
module      method
==========  ==============================================================================
ps          masked least squares (Eq. 2.17 with the mask's 0/1 weights)
fwlse       feasible weighted least squares (Section 3.4.1)
wps         weighted multi-zenith PS (Section 4.3): one masked solve per ring
robust      the default robust choice (see its docstring for the measured choice)
trim        per-pixel order statistics: drop the darkest and brightest fractions
l1          least absolute deviations (IRLS)
sbl         sparse Bayesian learning (Ikehata et al., CVPR 2012)
rpca        low-rank + sparse decomposition (Wu et al., ACCV 2010)
huber       M-estimator (IRLS, MAD scale)
cauchy      M-estimator (IRLS, MAD scale)
tukey       M-estimator (IRLS, MAD scale)
tsfit       per-pixel Lambert + Torrance-Sparrow fit (normal, rho_d, rho_s, lobe width m)
==========  ==============================================================================

Each module exposes ``METHOD`` (a :class:`psbench.registry.Method`) with its options
dataclass (a subclass of :class:`psbench.solve.base.Options`); the contract is
``func(problem, options) -> Fit`` (:mod:`psbench.solve.base`). They are registered
through the ``psbench.methods`` entry-point group of psbench's ``pyproject.toml``,
exactly as another package registers its own. Robust methods compose with any mask
expression: they use only the observations in ``problem.valid``. Shared machinery lives
in the private modules ``_robust_common`` (object pixels in an (n, k) layout, per-pixel
WLS) and ``_irls`` (reweighted least squares with per-pixel early stopping).
"""
