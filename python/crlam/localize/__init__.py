"""Monte Carlo localization on a fixed confidence-rich map (``crlam localize``).

The users of the library import from here: :class:`LocalizeConfig` (every setting, AMCL's
defaults where AMCL has one), :class:`Localizer` (feeds scans to the native filter and keeps one
pose per scan) and :func:`load_localization_map` (the map it runs on: a saved CRM or a Nav2 map
turned into a CRM prior). The modules, from the ground floor up:

- :mod:`crlam.localize.map`: the fixed map, and a Nav2 map's classes as CRM beliefs;
- :mod:`crlam.localize.run`: the settings and the filter's run.

Whole runs with their output folders are in :mod:`crlam.experiments.localize_run`.
"""

from __future__ import annotations

from crlam.localize.map import LocalizationMap, Nav2Prior, crm_from_nav2, load_localization_map
from crlam.localize.run import (
    EXACT_TOLERANCE,
    MODEL_PARAMS,
    MODELS,
    Convergence,
    LocalizeConfig,
    Localizer,
    LocalizeStep,
    converged_at,
)

__all__ = [
    "EXACT_TOLERANCE",
    "MODELS",
    "MODEL_PARAMS",
    "Convergence",
    "LocalizeConfig",
    "LocalizeStep",
    "Localizer",
    "converged_at",
    "LocalizationMap",
    "Nav2Prior",
    "crm_from_nav2",
    "load_localization_map",
]
