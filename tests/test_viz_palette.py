"""One colour per method across every figure (crlam.viz.palette)."""

from __future__ import annotations

import pytest

from crlam.experiments.iig import FUNCTIONS
from crlam.viz.palette import COLOURS, GROUND_TRUTH_STYLE, colour, label, line_style


def test_every_method_has_one_distinct_colour_whatever_its_spelling() -> None:
    assert colour("clam") == colour("RBPF-CLAM") == colour("rbpf_clam") == colour("weighted mean")
    assert colour("ogm") == colour("RBPF-OGM")
    assert colour("fsmi") == colour("OGMI") == colour("iig_mi")
    assert colour("ucrmi a=0.5") == colour("UCRMI alpha 0.25") == colour("ucrmi")
    # Every method that figures can show side by side has its own colour.
    side_by_side = ["ground truth", "odometry", "RBPF-CLAM", "RBPF-OGM"]
    assert len({colour(n) for n in side_by_side}) == len(side_by_side)
    functions = [*FUNCTIONS, "frontier"]
    assert len({colour(f) for f in functions}) == len(functions)
    assert label("clam") == "RBPF-CLAM" and label("ugpvr") == "UGPVR"


def test_an_unknown_method_is_an_error_not_a_colour_by_plot_order() -> None:
    with pytest.raises(KeyError, match="COLOURS"):
        colour("some new filter")


def test_the_ground_truth_is_drawn_dashed_above_every_estimate() -> None:
    gt = line_style("ground truth")
    assert gt["color"] == COLOURS["ground truth"] and gt["zorder"] == GROUND_TRUTH_STYLE["zorder"]
    for name in ("odometry", "RBPF-CLAM", "RBPF-OGM", "best path"):
        assert line_style(name)["zorder"] < gt["zorder"]
    assert line_style("reference") == gt
