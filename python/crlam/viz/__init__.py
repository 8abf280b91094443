"""Figures: maps, trajectories and errors (matplotlib, Agg backend, files only)."""

from crlam.viz.maps import add_scale_bar, plot_layer, save_crm_figure, save_world_figure

__all__ = ["add_scale_bar", "plot_layer", "save_crm_figure", "save_world_figure"]
