"""Map figures: occupancy drawn as 8-bit colours computed once per cell."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from crlam.viz.maps import show_occupancy  # noqa: E402


def test_show_occupancy_colours_each_cell_once() -> None:
    values = np.ma.masked_array([[0.0, 1.0], [0.5, 1.7]], mask=[[False, False], [True, False]])
    fig, ax = plt.subplots()
    show_occupancy(ax, values, (0.0, 2.0, 0.0, 2.0))
    (image,) = ax.get_images()
    rgba = np.asarray(image.get_array())
    plt.close(fig)
    assert rgba.dtype == np.uint8 and rgba.shape == (2, 2, 4)
    # gray_r: free (0) white, occupied (1) black; a value above 1 is drawn as 1; masked cells grey.
    assert rgba[0, 0].tolist() == [255, 255, 255, 255]
    assert rgba[0, 1].tolist() == [0, 0, 0, 255]
    assert rgba[1, 1].tolist() == [0, 0, 0, 255]
    assert rgba[1, 0].tolist() == [0xD8, 0xD8, 0xD8, 255]
    assert image.get_extent() == [0.0, 2.0, 0.0, 2.0]
