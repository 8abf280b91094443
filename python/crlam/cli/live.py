"""``--foxglove [PORT]``, ``--foxglove-host``, ``--foxglove-wait``: the live view's options (:mod:`crlam.live_view`).

Shared by ``crlam slam`` and the ROS 2 nodes (``crlam ros slam|localize|explore``).
"""

from __future__ import annotations

import argparse
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from crlam.cli.conventions import group

__all__ = ["add_foxglove_options", "announce_live_view", "hold_for_clients", "open_live_view"]


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a port number") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port {port} is outside 0..65535")
    return port


def add_foxglove_options(p: argparse.ArgumentParser, *, wait: bool = True) -> None:
    """Adds the live view's options to ``p`` (``wait``: also ``--foxglove-wait``, for offline runs)."""
    from crlam.live_view import DEFAULT_PORT

    g = group(p, "live view (Foxglove; needs crlam[live])")
    g.add_argument(
        "--foxglove",
        nargs="?",
        const=DEFAULT_PORT,
        type=_port,
        default=None,
        metavar="PORT",
        help=f"serve the map, /map_confidence, scans, particles, path and pose on a Foxglove WebSocket (ROS 2 messages) "
        f"at ws://HOST:PORT (default port {DEFAULT_PORT}; 0 picks a free one, printed)",
    )
    g.add_argument(
        "--foxglove-host",
        default="127.0.0.1",
        metavar="ADDRESS",
        help="address the Foxglove server binds to (default 127.0.0.1: this machine only; 0.0.0.0 lets other machines "
        "connect, with no authentication)",
    )
    if wait:
        g.add_argument(
            "--foxglove-wait",
            action="store_true",
            help="start the run once a client subscribes to /map, and after the run keep serving its final map until "
            "every client has left (or Ctrl-C)",
        )


@contextmanager
def open_live_view(args: argparse.Namespace, name: str) -> Iterator[Any]:
    """The :class:`~crlam.live_view.LiveView` of ``args`` (None without ``--foxglove``),
    stopped on exit. Call :func:`announce_live_view` once its channels exist."""
    if getattr(args, "foxglove", None) is None:
        yield None
        return
    from crlam.live_view import LiveView

    view = LiveView(port=args.foxglove, host=args.foxglove_host, name=name)
    try:
        yield view
    finally:
        view.close()


def announce_live_view(view: Any) -> None:
    """Prints the view's address (one line starting ``foxglove: serving``), once its channels
    are advertised: a client that connects then can subscribe to all of them at once."""
    if view is not None:
        print(f"foxglove: serving on {view.url} (port {view.port})", flush=True)


def slam_live_feed(args: argparse.Namespace, view: Any) -> Any:
    """The :class:`~crlam.experiments.slam_live_view.SlamLiveFeed` of ``view`` (None without a
    view), announced; with ``--foxglove-wait`` once a client subscribes to ``/map``."""
    if view is None:
        return None
    from crlam.experiments.slam_live_view import SlamLiveFeed

    feed = SlamLiveFeed(view)
    announce_live_view(view)
    if args.foxglove_wait:
        print("foxglove: waiting for a client to subscribe to /map", flush=True)
        view.wait_for_subscriber("/map")
    return feed


def hold_for_clients(view: Any, what: str) -> None:
    """Blocks while a client subscribes to anything of ``view`` (or until SIGINT/SIGTERM)."""
    stop = threading.Event()

    def on_signal(signum: int, frame: object) -> None:
        stop.set()

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        print(f"foxglove: {what}; serving until every client has left (Ctrl-C to stop)", flush=True)
        view.wait_until_unsubscribed(stop)
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
