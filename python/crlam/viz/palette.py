"""One colour per method, used by every figure of the project.

A method keeps its colour from figure to figure: RBPF-CLAM is blue in the demo's localization
figure, in the Table I figures and in a run folder's ``trajectory.png``; CRMI is green in the
IIG trees, the box plots and the exploration curves. The ground truth is black and is drawn on
top of the estimates (:data:`GROUND_TRUTH_STYLE`), so it is never hidden under them.

Names are matched case-insensitively and through :data:`ALIASES` (``"clam"``, ``"RBPF-CLAM"``
and ``"rbpf_clam"`` are one method). A variant written ``"NAME (detail)"`` or ``"NAME alpha 0.5"``
takes the colour of ``NAME``; :func:`colour` raises ``KeyError`` for a name it does not know, so a
new method gets a colour here instead of a colour picked by plot order.
"""

from __future__ import annotations

from typing import Any

from matplotlib import patheffects

__all__ = ["ALIASES", "COLOURS", "GROUND_TRUTH_STYLE", "colour", "label", "line_style"]

COLOURS: dict[str, str] = {
    # trajectories
    "ground truth": "#000000",
    "odometry": "#7f7f7f",
    "rbpf-clam": "#1f77b4",
    "rbpf-ogm": "#ff7f0e",
    # the other estimates a SLAM run records
    "best path": "#2ca02c",
    "best path means": "#98df8a",
    "highest-weight particle": "#d62728",
    "mode-seeking": "#9467bd",
    "smoothed": "#8c564b",
    # information functions and exploration strategies
    "crmi": "#2ca02c",
    "ucrmi": "#9467bd",
    "ogmi": "#d62728",
    "gpvr": "#8c564b",
    "ugpvr": "#e377c2",
    "frontier": "#17becf",
}
"""Hex colour of every method (keys in canonical lower-case form)."""

ALIASES: dict[str, str] = {
    "clam": "rbpf-clam",
    "rbpf_clam": "rbpf-clam",
    "ogm": "rbpf-ogm",
    "rbpf_ogm": "rbpf-ogm",
    "groundtruth": "ground truth",
    "reference": "ground truth",
    "truth": "ground truth",
    "estimate": "rbpf-clam",
    "weighted mean": "rbpf-clam",
    "best particle's path": "best path",
    "best_path": "best path",
    "best path's proposal means": "best path means",
    "max_weight": "highest-weight particle",
    "mode": "mode-seeking",
    "fsmi": "ogmi",
    "iig_mi": "ogmi",
    "nearest frontier": "frontier",
}
"""Other spellings of the names in :data:`COLOURS`."""

LABELS: dict[str, str] = {
    "rbpf-clam": "RBPF-CLAM",
    "rbpf-ogm": "RBPF-OGM",
    "crmi": "CRMI",
    "ucrmi": "UCRMI",
    "ogmi": "OGMI",
    "gpvr": "GPVR",
    "ugpvr": "UGPVR",
}

GROUND_TRUTH_STYLE: dict[str, Any] = {
    "color": COLOURS["ground truth"],
    "linewidth": 1.2,
    "linestyle": (0, (4, 2)),
    "zorder": 10,
    "path_effects": [patheffects.withStroke(linewidth=2.6, foreground="white", alpha=0.8)],
}
"""Matplotlib keywords of the ground truth: black, dashed, with a white halo that keeps it
visible over dark map cells, above every estimate."""


def _canonical(name: str) -> str:
    key = name.strip().lower()
    for sep in (" (", " alpha", " a=", ", "):
        if sep in key and key.split(sep)[0] in COLOURS.keys() | ALIASES.keys():
            key = key.split(sep)[0]
    return ALIASES.get(key, key)


def colour(name: str) -> str:
    """The hex colour of method ``name`` (see the module docstring for the names it knows)."""
    key = _canonical(name)
    if key not in COLOURS:
        raise KeyError(f"no colour for {name!r}; add it to crlam.viz.palette.COLOURS")
    return COLOURS[key]


def label(name: str) -> str:
    """The display name of method ``name`` (``"clam"`` -> ``"RBPF-CLAM"``); unknown names unchanged."""
    return LABELS.get(_canonical(name), name)


def line_style(name: str) -> dict[str, Any]:
    """Matplotlib keywords for a trajectory line of ``name``: its colour, and for the ground truth
    the dashed black line drawn on top (:data:`GROUND_TRUTH_STYLE`)."""
    if _canonical(name) == "ground truth":
        return dict(GROUND_TRUTH_STYLE)
    return {"color": colour(name), "linewidth": 0.9, "alpha": 0.9, "zorder": 5}
