"""``crlam bench``: the micro-benchmarks, printed as named figures (JSON)."""

from __future__ import annotations

import argparse
import json
import sys

from crlam.cli.conventions import ListAction, add_output_options, check_file_output, deprecated_alias, group, print_settings
from crlam.cli.options import positive_int

__all__ = ["add_parser", "cmd_bench"]


def cmd_bench(args: argparse.Namespace) -> int:
    from crlam.bench import run_benchmarks, write_json
    from crlam.io.run_folder import staged_file

    output = check_file_output(args)
    print_settings(args)
    result = run_benchmarks(args.only, quick=args.quick, repeats=args.repeats, progress=not args.quiet, verbose=args.verbose)
    if not args.quiet:
        cpu = " ".join(result["cpu_features"]) or "none"
        print(f"crlam bench: vector kernels at {result['simd']} (CRLAM_SIMD; CPU: {cpu})", file=sys.stderr)
    print(json.dumps(result["figures"] if not args.verbose else result, indent=2, sort_keys=True))
    if output is not None:
        with staged_file(output) as stage:
            write_json(result, stage)
    return 0


def add_parser(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    """Add ``bench`` to ``sub``."""
    p: argparse.ArgumentParser = sub.add_parser(
        "bench",
        help="run the micro-benchmarks and print named figures as JSON",
        description="Runs the core's micro-benchmarks (one thread, timed in Rust) and whole `crlam slam` runs of "
        "the default filter and of GMapping's setting on a simulated SICK log (slam_*_sick), and prints a JSON "
        "object of named figures, all measured in this run. The vector kernels run at the best instruction-set level the "
        "CPU supports unless the environment variable CRLAM_SIMD=scalar|avx2|avx512 lowers it (the level is "
        'reported as "simd" in the --out/--verbose result).',
    )
    run = group(p, "run control")
    run.add_argument("--only", action=ListAction, default=None, metavar="NAME", help="run only these figures")
    run.add_argument("--quick", action="store_true", help="small workloads (smoke test)")
    run.add_argument("--repeats", type=positive_int, default=3, help="best of N (default: 3)")
    add_output_options(p, out="also write the full result (figures, details, machine) to this JSON file", required=False)
    # -v also prints the full result instead of just the figures.
    deprecated_alias(p, "--json", "--out")
    p.set_defaults(func=cmd_bench)
    return p
