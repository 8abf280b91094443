"""``crlam info``: an information function evaluated at every free cell of a map."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from crlam.cli.conventions import add_output_options, deprecated_alias, group, map_file, print_settings, say
from crlam.cli.options import positive_float, positive_int, staged_output

__all__ = ["add_parser", "cmd_info"]


def cmd_info(args: argparse.Namespace) -> int:
    """Evaluate the function over the map's free cells and write surface.npy/png and info.json."""
    import numpy as np

    from crlam.errors import ConfigError
    from crlam.info import compute_surface, load_map_prior, make_function, prior_from_crm_mean
    from crlam.io.belief import load_belief
    from crlam.io.run_folder import moved
    from crlam.mapping import ConfidenceRichMap
    from crlam.viz.info import save_surface

    if (args.map is None) == (args.belief is None):
        raise ConfigError("give either a map file or --belief belief.npz")
    output = staged_output(args)  # the output is checked before the run, written after it
    f = make_function(
        args.function,
        z_max=args.max_range,
        resolution=args.resolution,
        n_beams=args.beams,
        beam_angles=args.beam_angles,
        mode=args.mode,
        alpha=args.alpha,
        n_particles=args.ucrmi_particles,
        crm_model=args.crm_model,
        crmi_variant=args.crmi_variant,
    )
    print_settings(args, function={"name": f.name, "units": f.units, "state": f.state_kind})
    if args.belief:
        archive = load_belief(args.belief)
        crm = ConfidenceRichMap.from_archive(archive)
        mean = crm.expected_occupancy()
        prior = prior_from_crm_mean(mean.values, mean.origin, mean.resolution)
        state: Any = crm.native if f.state_kind == "crm" else f.make_state(prior.lattice)
        if f.state_kind == "crm" and abs(archive.resolution - args.resolution) > 1e-12:
            say(args, f"note: the belief's resolution {archive.resolution} m sets the CRM grid (not --resolution)")
    else:
        prior = load_map_prior(args.map, resolution=args.resolution, p_occupied=args.p_occupied, p_free=args.p_free)
        state = f.make_state(prior.lattice)
    if not prior.free.any():
        print(f"crlam info: {args.map}: the map has no free cell to evaluate")
        return 2
    n = int(prior.free.sum())
    say(args, f"{f.name} ({f.units}) at {n} free cells of {prior.source} ...")
    surface = compute_surface(f, state, prior, heading=args.heading, seed=args.seed)
    with output as stage:
        paths = save_surface(surface, stage)
    s = surface.summary()
    fin = surface.values[np.isfinite(surface.values)]
    print(
        f"min {fin.min():.4g}  max {fin.max():.4g}  mean {fin.mean():.4g} {f.units}; "
        f"{s['wall_time_s']:.2f} s wall ({s['us_per_pose_wall']:.0f} µs per pose, {s['threads']} threads)"
    )
    for key, p in paths.items():
        print(f"  {key:<8s} {moved(p, stage, Path(args.out))}")
    return 0


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``info`` to ``subparsers``."""
    from crlam.info import FUNCTION_NAMES

    p: argparse.ArgumentParser = subparsers.add_parser(
        "info",
        help="evaluate an information function at every free cell of a map",
        description="Evaluates CRMI, UCRMI, FSMI/OGMI, the IIG 'mi' heuristic, GPVR or UGPVR at every free cell of a "
        "map (a PGM read as the planner reads the Cave map, a Nav2 YAML map, or a saved CRM belief.npz) and writes "
        "surface.npy (the gain per cell, NaN elsewhere), surface.png (heat map over the map) and info.json "
        "(function, settings, units, min/max/mean, time per pose). Map priors follow the planner: occupied "
        "cells 0.85, free 0.3, unknown 0.5, with a 1 m free margin; CRM functions start from tilted pmfs with "
        "those means.",
    )
    inp = group(p, "input")
    inp.add_argument("map", nargs="?", type=map_file, help="map.pgm or map.yaml, or a map dataset (cave-map); omit with --belief")
    inp.add_argument("--belief", type=map_file, help="a belief.npz: CRM functions use it; the others its mean map")
    inp.add_argument("--resolution", type=positive_float, default=0.2, help="metres per pixel of a bare PGM (default: 0.2)")
    inp.add_argument("--p-occupied", type=float, default=0.85, help="prior of occupied cells (default: 0.85)")
    inp.add_argument("--p-free", type=float, default=0.3, help="prior of free cells (default: 0.3)")
    fn = group(p, "information function")
    fn.add_argument("--function", required=True, choices=FUNCTION_NAMES, help="the information function")
    fn.add_argument("--mode", choices=("clean", "reference"), default="clean", help="reference quirks or clean (default)")
    fn.add_argument("--alpha", type=float, default=0.5, help="UCRMI weight of the map term (default: 0.5)")
    fn.add_argument("--ucrmi-particles", type=positive_int, default=100, help="UCRMI pose particles (default: 100)")
    fn.add_argument(
        "--crmi-variant",
        choices=("exact", "ml_scan_binary", "r1_map"),
        default="exact",
        help="CRMI by the exact channel (default) or the authors' approximations, for comparison",
    )
    fn.add_argument("--crm-model", choices=("ijrr", "mixture"), default="ijrr", help="CRM mapping model (default: ijrr)")
    fn.add_argument("--heading", type=float, default=0.0, help="candidate heading in rad (default: 0)")
    fn.add_argument("--seed", type=int, default=0, help="seed of the pose-aware functions (default: 0)")
    sensor = group(p, "sensor", "the virtual scan whose information is evaluated")
    sensor.add_argument("--max-range", type=positive_float, default=5.0, help="beam length in metres (default: 5)")
    sensor.add_argument("--beams", type=positive_int, default=10, help="beams per virtual scan (default: 10)")
    sensor.add_argument("--beam-angles", choices=("distinct", "reference"), default=None, help="default: by --mode")
    add_output_options(p)
    deprecated_alias(p, "--z-max", "--max-range")
    deprecated_alias(p, "--particles", "--ucrmi-particles")
    p.set_defaults(func=cmd_info)
    return p
