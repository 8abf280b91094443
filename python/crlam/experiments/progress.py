"""The progress bar of a run over a log's scans (``crlam slam``, ``crlam localize``)."""

from __future__ import annotations

import os
from typing import Any

from tqdm import tqdm

from crlam.io.logs import count_scans

__all__ = ["scan_progress_bar"]


def scan_progress_bar(
    log_path: str | os.PathLike[str],
    *,
    desc: str,
    progress: bool,
    max_scans: int | None = None,
    bag_options: dict[str, Any] | None = None,
) -> tqdm[Any]:
    """A bar counting the log's scans, with their total (so an ETA) from :func:`count_scans`
    when ``progress`` is on (the count is one pass over the log, skipped when the bar is off)."""
    return tqdm(
        total=count_scans(log_path, max_scans, bag_options=bag_options) if progress else None,
        desc=desc,
        unit="scan",
        disable=not progress,
        mininterval=1.0,
    )
