"""``crlam ros``: crlam as live ROS 2 nodes over DDS, without a ROS installation (``crlam[ros]``).

``crlam ros slam`` runs RBPF-CLAM on ``/scan`` + ``/odom`` and publishes the map and
map -> odom; ``crlam ros play BAG`` publishes a bag onto DDS. Both run on the loopback interface
unless ``--dds-config`` says otherwise (:mod:`crlam.ros.dds`).
"""

from __future__ import annotations

import argparse
import math
import signal
import threading
from typing import Any

from crlam.cli.conventions import add_output_options, group, input_file, say
from crlam.cli.live import add_foxglove_options, announce_live_view, open_live_view

__all__ = ["add_parser", "cmd_ros_explore", "cmd_ros_localize", "cmd_ros_play", "cmd_ros_slam"]


def _dds_options(p: argparse.ArgumentParser) -> None:
    g = group(p, "DDS")
    g.add_argument("--domain", type=int, default=None, help="DDS domain (default: ROS_DOMAIN_ID, else 0)")
    g.add_argument(
        "--dds-config",
        default="loopback",
        metavar="loopback|env|FILE",
        help="loopback (default: interface lo, peers on 127.0.0.1, no multicast), env (the environment's CYCLONEDDS_URI, "
        "for a robot whose nodes run on other machines) or a Cyclone DDS XML file",
    )


def _check_out(args: argparse.Namespace) -> None:
    """An existing -o/--out is refused without --force (the node's saves then replace it)."""
    from crlam.io.run_folder import check_output

    check_output(args.out, force=args.force, what="output folder")


def _need_cyclonedds() -> None:
    try:
        import cyclonedds  # noqa: F401
    except ImportError:
        from crlam.errors import ConfigError

        raise ConfigError("crlam ros needs Cyclone DDS's Python binding: pip install 'crlam[ros]'") from None


def cmd_ros_play(args: argparse.Namespace) -> int:
    _need_cyclonedds()
    from crlam.ros.play import play_bag

    stats = play_bag(
        args.bag,
        rate=math.inf if args.rate == 0 else args.rate,
        clock=args.clock,
        topics=args.topics,
        lockstep=args.lockstep,
        wait_for=args.wait_for_subscribers,
        domain=args.domain,
        dds_config=args.dds_config,
    )
    total = sum(stats.published.values())
    say(args, f"published {total} messages on {len(stats.published)} topics in {stats.wall_time_s:.1f} s")
    for topic, n in sorted(stats.published.items()):
        say(args, f"  {topic}: {n}")
    for topic, why in sorted(stats.skipped_topics.items()):
        say(args, f"  skipped {topic}: {why}")
    return 0


def cmd_ros_slam(args: argparse.Namespace) -> int:
    _need_cyclonedds()
    from crlam.ros.params import load_params_file, split_parameters
    from crlam.ros.slam_node import SlamNode

    params = load_params_file(args.params_file, "crlam_slam") if args.params_file else {}
    if args.out:
        _check_out(args)
        params["output_folder"] = args.out
    if args.use_sim_time:
        params["use_sim_time"] = True
    node_params, overrides = split_parameters(params, args.params_file or "parameters")
    node = SlamNode(node_params, overrides, domain=args.domain, dds_config=args.dds_config)
    return _spin(args, node)


def cmd_ros_localize(args: argparse.Namespace) -> int:
    _need_cyclonedds()
    from crlam.ros.localize_node import LocalizeNode, split_localize_parameters
    from crlam.ros.params import load_params_file

    params = load_params_file(args.params_file, "crlam_localize") if args.params_file else {}
    if args.out:
        _check_out(args)
        params["output_folder"] = args.out
    if args.use_sim_time:
        params["use_sim_time"] = True
    if args.initial_pose is not None:
        params["initial_pose"] = list(args.initial_pose)
    node_params, overrides, map_options = split_localize_parameters(params, args.params_file or "parameters")
    node = LocalizeNode(node_params, overrides, args.map, map_options=map_options, domain=args.domain, dds_config=args.dds_config)
    return _spin(args, node)


def cmd_ros_explore(args: argparse.Namespace) -> int:
    _need_cyclonedds()
    from crlam.ros.explore_node import ExploreNode, split_explore_parameters
    from crlam.ros.params import load_params_file, split_parameters

    params = load_params_file(args.params_file, "crlam_explore") if args.params_file else {}
    if args.out:
        _check_out(args)
        params["output_folder"] = args.out
    if args.use_sim_time:
        params["use_sim_time"] = True
    explore, rest = split_explore_parameters(params)
    if args.function:
        explore["function"] = args.function
    node_params, overrides = split_parameters(rest, args.params_file or "parameters")
    node = ExploreNode(node_params, overrides, explore, domain=args.domain, dds_config=args.dds_config)
    return _spin(args, node)


def _spin(args: argparse.Namespace, node: Any) -> int:
    """Runs ``node`` until SIGINT or SIGTERM, then stops it (saving to its output folder, if any)."""
    done = threading.Event()

    def on_signal(signum: int, frame: object) -> None:
        done.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    name = f"crlam ros {args.ros_command}"
    with open_live_view(args, name) as view:
        node.live_view = view
        node.start()
        announce_live_view(view)
        say(args, f"{name}: running on DDS domain {node.dds.domain} ({node.dds.config_description}); Ctrl-C to stop")
        done.wait()
        node.stop(save=True)
    say(args, f"{name}: stopped; {node.counters}")
    return 0


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``ros`` (with ``slam`` and ``play``) to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "ros", help="live ROS 2 nodes over DDS, no ROS installation needed (crlam[ros])", description=__doc__
    )
    rs = p.add_subparsers(dest="ros_command", metavar="ROS_COMMAND")
    rs.required = True

    play = rs.add_parser("play", help="publish a ROS 1 / ROS 2 / MCAP bag onto DDS with ROS 2 QoS and /clock")
    g = group(play, "input")
    g.add_argument("bag", type=input_file, help="ROS 2 bag folder, .mcap or ROS 1 .bag")
    g.add_argument("--topics", nargs="+", default=None, help="only these topics")
    rc = group(play, "run control")
    rc.add_argument("--rate", type=float, default=1.0, help="playback speed factor; 0 publishes as fast as possible")
    rc.add_argument("--clock", action="store_true", help="publish /clock (bag time) for nodes with use_sim_time")
    rc.add_argument(
        "--lockstep",
        action="store_true",
        help="before each scan wait until crlam ros slam reports it handled the scans before (deterministic runs)",
    )
    rc.add_argument(
        "--wait-for-subscribers", nargs="+", default=None, metavar="TOPIC", help="wait until these topics have a subscriber"
    )
    add_output_options(play, out=None, replace=None)
    _dds_options(play)
    play.set_defaults(func=cmd_ros_play)

    slam = rs.add_parser("slam", help="RBPF-CLAM on /scan + /odom, publishing /map and map -> odom")
    g = group(slam, "settings")
    g.add_argument("--params-file", metavar="YAML", help="ROS 2 parameter file (crlam_slam: ros__parameters: ...)")
    g.add_argument("--use-sim-time", action="store_true", help="stamp output with /clock")
    add_output_options(
        slam,
        out="run folder written on a save request and on exit (each save replaces it whole)",
        required=False,
    )
    _dds_options(slam)
    add_foxglove_options(slam, wait=False)
    slam.set_defaults(func=cmd_ros_slam)

    exp = rs.add_parser("explore", help="crlam ros slam that publishes /goal_pose chosen by CRMI or UCRMI on the live map")
    g = group(exp, "settings")
    g.add_argument("--params-file", metavar="YAML", help="ROS 2 parameter file (crlam_explore: ros__parameters: ...)")
    g.add_argument("--function", choices=("crmi", "ucrmi"), help="information function (default crmi; explore_function)")
    g.add_argument("--use-sim-time", action="store_true", help="stamp output with /clock")
    add_output_options(
        exp,
        out="run folder written on a save request and on exit (each save replaces it whole; the output_folder parameter)",
        required=False,
    )
    _dds_options(exp)
    add_foxglove_options(exp, wait=False)
    exp.set_defaults(func=cmd_ros_explore)

    loc = rs.add_parser("localize", help="Monte Carlo localization on a known map, /initialpose from RViz")
    g = group(loc, "input")
    g.add_argument("--map", required=True, type=input_file, help="Nav2 map .yaml, crlam run folder or belief.npz")
    g = group(loc, "settings")
    g.add_argument("--params-file", metavar="YAML", help="ROS 2 parameter file (crlam_localize: ros__parameters: ...)")
    g.add_argument("--use-sim-time", action="store_true", help="stamp output with /clock")
    g.add_argument(
        "--initial-pose", nargs=3, type=float, metavar=("X", "Y", "THETA"), help="start around this pose (else global)"
    )
    add_output_options(
        loc,
        out="folder written on a save request and on exit (each save replaces it whole)",
        required=False,
    )
    _dds_options(loc)
    add_foxglove_options(loc, wait=False)
    loc.set_defaults(func=cmd_ros_localize)
    return p
