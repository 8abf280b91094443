"""``crlam explore``: greedy information-driven exploration of a simulated world."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from crlam.cli.conventions import add_output_options, deprecated_alias, group, print_settings, say, world_arg
from crlam.cli.live import add_foxglove_options, announce_live_view, hold_for_clients, open_live_view
from crlam.cli.options import finite_float, positive_float, positive_int, staged_output

__all__ = ["add_parser", "cmd_explore"]


def cmd_explore(args: argparse.Namespace) -> int:
    """Explore the world and write the run folder."""
    from crlam.experiments.explore import ExploreConfig, default_start, explore, write_explore_folder
    from crlam.io.run_folder import moved
    from crlam.sim.worlds import get_world

    output = staged_output(args)  # the output is checked before the run, written after it
    world = get_world(args.world, seed=args.world_seed, resolution=args.resolution)
    cfg = ExploreConfig(
        function=args.function,
        alpha=args.alpha,
        budget_m=args.budget,
        threshold=args.threshold,
        n_candidates=args.candidates,
        radius_m=args.radius,
        cost_weight=args.cost_weight,
        sensor_range=args.max_range,
        particles=args.ucrmi_particles,
        seed=args.seed,
        slam=args.slam,
        slam_particles=args.slam_particles,
    )
    start = tuple(args.start) + (0.0,) if args.start else default_start(world, cfg.resolution)
    print_settings(args, explore_settings=cfg)
    say(args, f"exploring {world.name} from ({start[0]:.1f}, {start[1]:.1f}) with {cfg.function} ...")
    with open_live_view(args, "crlam explore") as view:
        feed = None
        if view is not None:
            from crlam.experiments.explore_live_view import ExploreLiveFeed

            feed = ExploreLiveFeed(view)
            announce_live_view(view)
            if args.foxglove_wait:
                print("foxglove: waiting for a client to subscribe to /map", flush=True)
                view.wait_for_subscriber("/map")
        run = explore(world, (start[0], start[1], start[2]), cfg, progress=not args.quiet, verbose=args.verbose, on_event=feed)
        with output as stage:
            files = write_explore_folder(run, stage, gif=not args.no_gif)
        if view is not None and view.republish("/map"):  # the last decision's map, once the folder is in place
            print(f"foxglove: final map published on {view.url}", flush=True)
        if view is not None and args.foxglove_wait:
            hold_for_clients(view, f"the run is written to {args.out}")
    last = run.decisions[-1] if run.decisions else {}
    print(
        f"stopped ({run.stop}) after {len(run.decisions)} decisions, {run.distance:.1f} m; "
        f"explored {last.get('explored_m2', 0):.0f} m^2, map error {last.get('map_error', 0):.3f}"
    )
    if args.slam:
        err = ((run.estimates[:, :2] - run.poses[:, :2]) ** 2).sum(axis=1) ** 0.5
        print(f"pose error: mean {err.mean():.3f} m, max {err.max():.3f} m; bumps {run.bumps}")
    for key, p in files.items():
        print(f"  {key:<16s} {moved(p, stage, Path(args.out))}")
    return 0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``explore`` to ``subparsers``."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "explore",
        help="greedy information-driven exploration of a simulated world (the paper's Fig. 1)",
        description="A simulated robot with a 360 deg range sensor explores a world it does not know, with known "
        "poses or (--slam) RBPF-CLAM: each step it evaluates reachable known-free candidates and frontier cells "
        "with the information "
        "function in one batch, drives the shortest known-free path to the best one while scanning, and stops "
        "when the best gain is below --threshold, the --budget is spent or nothing reachable is left. Writes "
        "trajectory.tum, groundtruth.tum, map.pgm/yaml, belief.npz, metrics.json, progress.csv, exploration.png "
        "(trajectory over the final CRM and its CRMI surface), progress.png and exploration.gif.",
    )
    inp = group(p, "world")
    inp.add_argument(
        "--world", type=world_arg, default="office", help="museum | office | a map file (PGM/PNG/Nav2 YAML) or map dataset"
    )
    inp.add_argument("--world-seed", type=int, default=0, help="seed of a procedural world (default: 0)")
    inp.add_argument(
        "--resolution",
        type=positive_float,
        default=None,
        help="m per pixel of a bare image; cell size of a procedural world (default: 0.05)",
    )
    inp.add_argument("--start", type=finite_float, nargs=2, metavar=("X", "Y"), help="start position (default: a free corner)")
    fn = group(p, "planner")
    fn.add_argument("--function", choices=("crmi", "ucrmi", "fsmi", "frontier"), default="crmi", help="information function")
    fn.add_argument("--alpha", type=finite_float, default=0.5, help="UCRMI weight of the map term (default: 0.5)")
    fn.add_argument("--ucrmi-particles", type=positive_int, default=30, help="UCRMI pose particles (default: 30)")
    fn.add_argument("--candidates", type=positive_int, default=200, help="candidates per decision (default: 200)")
    fn.add_argument("--radius", type=positive_float, default=5.0, help="candidate radius in metres (default: 5)")
    fn.add_argument("--cost-weight", type=finite_float, default=0.0, help="score = gain / cost^w (default 0: pure gain)")
    fn.add_argument("--threshold", type=finite_float, default=0.1, help="stop when the best gain is below this (default: 0.1)")
    fn.add_argument("--budget", type=positive_float, default=150.0, help="travel budget in metres (default: 150)")
    sensor = group(p, "sensor")
    sensor.add_argument("--max-range", type=positive_float, default=5.0, help="sensor range in metres (default: 5)")
    slam = group(p, "filter")
    slam.add_argument(
        "--slam",
        action="store_true",
        help="estimate the pose with RBPF-CLAM from noisy odometry and the scans (decisions use its best map and "
        "its estimate; UCRMI sees its particle set) instead of knowing it",
    )
    slam.add_argument("--slam-particles", type=positive_int, default=30, help="RBPF-CLAM particles (default: 30)")
    slam.add_argument("--seed", type=int, default=0, help="seed of the sensor noise and candidate sampling")
    out = add_output_options(p)
    out.add_argument("--no-gif", action="store_true", help="skip the animation")
    add_foxglove_options(p)
    deprecated_alias(p, "--world-resolution", "--resolution")
    deprecated_alias(p, "--particles", "--ucrmi-particles")
    p.set_defaults(func=cmd_explore)
    return p
