"""Information functions for choosing where to sense next (crm-spec 5-6, planner-spec 4-6).

>>> from crlam.info import make_function, load_map_prior, compute_surface
>>> prior = load_map_prior("cave.pgm")                      # doctest: +SKIP
>>> f = make_function("crmi")                               # doctest: +SKIP
>>> surface = compute_surface(f, f.make_state(prior.lattice), prior)  # doctest: +SKIP
"""

from crlam.info.functions import FUNCTION_NAMES, Evaluation, InformationFunction, make_function
from crlam.info.prior import MapPrior, lattice_from_obstacles, load_map_prior, prior_from_crm_mean
from crlam.info.surface import InfoSurface, compute_surface

__all__ = [
    "FUNCTION_NAMES",
    "Evaluation",
    "InfoSurface",
    "InformationFunction",
    "MapPrior",
    "compute_surface",
    "lattice_from_obstacles",
    "load_map_prior",
    "make_function",
    "prior_from_crm_mean",
]
