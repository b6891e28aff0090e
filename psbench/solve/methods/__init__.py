"""The methods of :func:`psbench.solve`, one module per method.

======  ==================================================================
module  method
======  ==================================================================
ps      masked least squares (Eq. 2.17 with the mask's 0/1 weights)
fwlse   feasible weighted least squares (Section 3.4.1)
wps     weighted multi-zenith PS (Section 4.3): one masked solve per ring
======  ==================================================================

Each module exposes ``METHOD`` (a :class:`psbench.registry.Method`) with its options
dataclass (a subclass of :class:`psbench.solve.base.Options`); the contract is
``func(problem, options) -> Fit`` (:mod:`psbench.solve.base`). They are registered
through the ``psbench.methods`` entry-point group of psbench's ``pyproject.toml``,
exactly as another package registers its own.
"""
