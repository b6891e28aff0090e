"""Normals -> heights: Poisson (exact, DCT, sparse), Frankot-Chellappa and bilateral
integration. :func:`integrate` (module :mod:`~psbench.integrate.poisson`) chooses among
them; :mod:`~psbench.integrate.bilateral` keeps height jumps (BiNI)."""
from .._shared.deprecation import renamed_names
from .bilateral import bilateral_integrate
from .poisson import INTEGRATORS, NZ_MIN, gradients, integrate

__all__ = ["integrate", "gradients", "INTEGRATORS", "NZ_MIN", "bilateral_integrate"]

__getattr__ = renamed_names(globals(), {"METHODS": "INTEGRATORS"})
