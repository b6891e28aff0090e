"""The methods of :func:`psbench.solve`, one module per method, one subpackage per
family of several modules.

=================  =======================================================================
module             method
=================  =======================================================================
ps                 masked least squares (Eq. 2.17 with the mask's 0/1 weights)
fwlse              feasible weighted least squares (Section 3.4.1)
wps/               weighted multi-zenith PS (Section 4.3): one masked solve per ring
tsfit/             per-pixel Lambert + Torrance-Sparrow fit (normal, rho_d, rho_s, lobe m)
robust/            the robust family; the package itself is ``robust``, the default robust
                   choice (module ``choice``, see its docstring for the measured choice)
robust/trim        per-pixel order statistics: drop the darkest and brightest fractions
robust/l1          least absolute deviations (IRLS)
robust/sbl         sparse Bayesian learning (Ikehata et al., CVPR 2012)
robust/rpca        low-rank + sparse decomposition (Wu et al., ACCV 2010)
robust/huber       M-estimator (IRLS, MAD scale)
robust/cauchy      M-estimator (IRLS, MAD scale)
robust/tukey       M-estimator (IRLS, MAD scale)
=================  =======================================================================

Each method module exposes ``METHOD`` (a :class:`psbench.registry.Method`) with its
options dataclass (a subclass of :class:`psbench.solve.base.Options`); the contract is
``func(problem, options) -> Fit`` (:mod:`psbench.solve.base`). They are registered
through the ``psbench.methods`` entry-point group of psbench's ``pyproject.toml``,
exactly as another package registers its own (and found by convention in a source
tree: the public modules here and in the family subpackages). Robust methods compose
with any mask expression: they use only the observations in ``problem.valid``. A
family's shared machinery is private to its subpackage (``robust/_common``,
``robust/_irls``, ``tsfit/_lm``, ``wps/_kernel`` ...).
"""
