"""The memory of this process: its high-water mark, and handing freed memory back to the system."""

from __future__ import annotations

import resource
import sys


def peak_rss_mb() -> float:
    """Peak resident memory of this process (MB).

    On Linux this is ``VmHWM`` from ``/proc/self/status``: the high-water mark of this program's
    own memory since it started. ``ru_maxrss`` is not: a process started by ``fork`` (as the
    ``spawn`` workers of a sweep are, before their ``exec``) inherits the parent's peak, so a run
    started by a parent that had just simulated a large log reported the parent's memory. Other
    systems fall back to ``ru_maxrss``.
    """
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def return_freed_memory() -> None:
    """Hands the memory this process has freed back to the system, where the C library can.

    The particles' map tiles are allocated and freed on the filter's worker threads, in those
    threads' malloc arenas; glibc keeps freed arena memory mapped for the same thread's later
    allocations, so the main thread's figures would be allocated on top of it. ``malloc_trim``
    returns it (glibc only; a no-op elsewhere).
    """
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        # The symbols already loaded into the process: the C library's among them.
        trim = getattr(ctypes.CDLL(None), "malloc_trim", None)
    except OSError:
        return
    if trim is not None:  # musl has no malloc_trim
        trim(0)
