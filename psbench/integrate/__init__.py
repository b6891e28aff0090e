"""Normals -> heights: Poisson (exact, DCT, sparse), Frankot-Chellappa and bilateral
integration. :func:`integrate` (module :mod:`~psbench.integrate.poisson`) chooses among
them; :mod:`~psbench.integrate.bilateral` keeps height jumps (BiNI)."""
from .bilateral import bilateral_integrate
from .poisson import METHODS, NZ_MIN, gradients, integrate

__all__ = ["integrate", "gradients", "METHODS", "NZ_MIN", "bilateral_integrate"]
