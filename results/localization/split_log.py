"""Splits a CARMEN log into two halves by laser scans, in file order.

    python split_log.py LOG FIRST_OUT SECOND_OUT

The first half holds every line before the (n // 2)-th laser line (FLASER, RLASER or
ROBOTLASER1; n counted in the whole log), the second half the header (the lines before the
first laser or ODOM line: comments and PARAM lines, e.g. the laser offset) and every line from
there on. Both are written gzip-compressed when their name ends in .gz. Used by the continue
experiment of results/localization/README.md.
"""

from __future__ import annotations

import bz2
import gzip
import sys
from pathlib import Path
from typing import IO

LASER = ("FLASER", "RLASER", "ROBOTLASER1")


def _open_text(path: str, mode: str) -> IO[str]:
    if path.endswith(".bz2"):
        return bz2.open(path, mode + "t")
    if path.endswith(".gz"):
        return gzip.open(path, mode + "t")
    return open(path, mode)


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print(__doc__)
        return 2
    src, first, second = argv
    with _open_text(src, "r") as fh:
        lines = fh.readlines()
    is_laser = [ln.split(maxsplit=1)[0] in LASER if ln.strip() else False for ln in lines]
    n = sum(is_laser)
    if n < 2:
        print(f"{src}: {n} laser lines, nothing to split")
        return 2
    k, cut = 0, len(lines)
    for i, laser in enumerate(is_laser):
        if laser:
            if k == n // 2:
                cut = i
                break
            k += 1
    header_end = next(i for i, ln in enumerate(lines) if ln.split(maxsplit=1)[:1] and ln.split(maxsplit=1)[0] in (*LASER, "ODOM"))
    with _open_text(first, "w") as fh:
        fh.writelines(lines[:cut])
    with _open_text(second, "w") as fh:
        fh.writelines(lines[:header_end] + lines[cut:])
    print(f"{src}: {n} laser lines -> {Path(first).name} ({n // 2}), {Path(second).name} ({n - n // 2})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
