"""A sweep of the public API with hostile arguments (run by tests/test_hostile_api.py in a child
process with a bounded address space, so that a regression cannot take the machine down).

Every constructor, method and function of ``crlam._native`` and the main entry points of the
Python API are called with valid arguments, then once for each (parameter, hostile value): NaN,
infinities, huge and negative numbers, huge integers, empty, non-finite and wrongly shaped arrays,
None and strings. Allowed outcomes are success, a :class:`crlam.errors.CrlamError` subclass, and
``TypeError`` / ``ValueError`` / ``OverflowError`` for an argument of the wrong Python type or out
of the range of its C type. Anything else (``PanicException``, ``MemoryError``, ``IndexError``,
``ZeroDivisionError``, ...) is reported. Prints a JSON object: calls made, failures.
"""

from __future__ import annotations

import json
import math
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

NAN, INF = math.nan, math.inf

FLOATS: list[Any] = [NAN, INF, -INF, -1.0, 0.0, 1e308, -1e308, 5e-324, 1e19]
INTS: list[Any] = [-1, 0, 2**31, 2**63 - 1, -(2**63), 2**64]
ARRAYS: list[Any] = [
    np.empty(0),
    np.full(3, NAN),
    np.full(3, INF),
    np.full(3, 1e308),
    np.zeros((2, 0)),
    np.zeros((0, 3)),
    np.zeros((4, 3, 2)),
    np.arange(12.0).reshape(3, 4)[:, ::2],  # not contiguous
    np.zeros(3, dtype=np.int64),
]
OTHER: list[Any] = [None, "x", "", (NAN, NAN), (), (1e308, -1e308), [INF] * 3, (2**63 - 1, 2**63 - 1, 2**63 - 1, 2**63 - 1)]
HOSTILE = FLOATS + INTS + ARRAYS + OTHER

ALLOWED: tuple[type[BaseException], ...] = (TypeError, ValueError, OverflowError)


def _specs() -> list[tuple[str, Callable[..., Any], dict[str, Any]]]:
    """(name, callable, valid keyword arguments) of every entry point swept."""
    from crlam import _native as n

    sm = n.SensorModel()
    crm = n.CrmMap(0.2)
    crm.update_scan(np.zeros(3), np.linspace(-1, 1, 20), np.full(20, 3.0), sm)
    ogm = n.LogOddsMap(0.2)
    lat = n.OccupancyLattice(np.full((20, 20), 0.3), 0.2, (0.0, 0.0))
    gp = n.GpVarianceMap(lat, 1.0)
    crmi = n.InfoFunction.crmi(sm)
    fsmi = n.InfoFunction.fsmi()
    ucrmi = n.InfoFunction.ucrmi(sm, sm, n_particles=10)
    clam = n.ClamFilter(np.zeros(3), sm, sm, n_particles=3)
    ogmf = n.OgmFilter(np.zeros(3), n_particles=3)
    angles, ranges = np.linspace(-1, 1, 20), np.full(20, 3.0)
    upd = crmi.evaluate(crm, np.array([1.0, 1.0, 0.0]))[2]
    belief = n.ParticleBelief.from_particles(np.zeros((3, 3)), np.zeros(3), 0.0)
    occ = np.zeros((10, 10), dtype=np.uint8)
    occ[0, :] = 1
    pos = np.zeros((1, 2))
    iig_opts = {"start": (2.0, 2.0), "max_iterations": 3, "max_wall_seconds": 5.0}
    matcher = n.LocalMapMatcher()
    matcher.insert(np.zeros(3), angles, ranges, np.zeros(3))
    return [
        (
            "SensorModel",
            n.SensorModel,
            dict(kind="ijrr", z_max=8.0, resolution=0.2, cause_kernel="midpoint", sigma_hit=0.05, lambda_short=0.2, z_min=0.0),
        ),
        ("SensorModel.on_ray", sm.on_ray, dict(z=1.0, d=1.0)),
        ("SensorModel.infinity", sm.infinity, dict(z=1.0)),
        (
            "CrmMap",
            n.CrmMap,
            dict(resolution=0.2, origin=(0.0, 0.0), n_levels=10, levels="midpoints", prior_mean=0.3, tile_size=32, extent=None),
        ),
        ("CrmMap.cell_of", crm.cell_of, dict(x=1.0, y=1.0)),
        ("CrmMap.mean_at", crm.mean_at, dict(ix=1, iy=1)),
        ("CrmMap.cell", crm.cell, dict(ix=1, iy=1)),
        (
            "CrmMap.update_scan",
            crm.copy().update_scan,
            dict(pose=np.zeros(3), angles=angles, ranges=ranges, model=sm, beam_stride=1),
        ),
        (
            "CrmMap.update_scans",
            crm.copy().update_scans,
            dict(poses=np.zeros((1, 3)), angles=angles, ranges=ranges[None, :], model=sm),
        ),
        ("CrmMap.scan_log_likelihood", crm.scan_log_likelihood, dict(pose=np.zeros(3), angles=angles, ranges=ranges, model=sm)),
        ("CrmMap.beliefs", crm.beliefs, dict(rect=(0, 0, 3, 3))),
        ("CrmMap.derived_maps", crm.derived_maps, dict(rect=(0, 0, 3, 3))),
        ("CrmMap.set_beliefs", crm.copy().set_beliefs, dict(ix0=0, iy0=0, beliefs=np.full((2, 2, 10), 0.1))),
        ("LogOddsMap", n.LogOddsMap, dict(resolution=0.2, z_max=8.0, l_occ=1.0, l_free=-0.5, base=2.0, tile_size=32)),
        ("LogOddsMap.update_scan", ogm.copy().update_scan, dict(pose=np.zeros(3), angles=angles, ranges=ranges)),
        ("LogOddsMap.update_scans", ogm.copy().update_scans, dict(poses=np.zeros((1, 3)), angles=angles, ranges=ranges[None, :])),
        ("LogOddsMap.log_odds", ogm.log_odds, dict(rect=(0, 0, 3, 3))),
        (
            "ClamFilter",
            n.ClamFilter,
            dict(
                initial_pose=np.zeros(3),
                mapping_model=sm,
                weight_model=sm,
                n_particles=3,
                resolution=0.2,
                tempering=1.0,
                init_sigma=(0.0, 0.0, 0.0),
                motion_params=None,
                linear_update=0.0,
                lattice_step=(0.05, 0.025),
                seed=0,
            ),
        ),
        ("ClamFilter.process", clam.process, dict(odom=np.zeros(3), angles=angles, ranges=ranges, laser_offset=np.zeros(3))),
        (
            "ClamFilter.process_many",
            clam.process_many,
            dict(odoms=np.zeros((1, 3)), angles=angles, ranges=ranges[None, :], laser_offset=np.zeros(3)),
        ),
        ("ClamFilter.ancestor_means", clam.ancestor_means, dict(max_lag=1, proposal_means=False)),
        (
            "OgmFilter",
            n.OgmFilter,
            dict(initial_pose=np.zeros(3), n_particles=3, resolution=0.2, usable_range=30.0, weight_smoothing=3.0, seed=0),
        ),
        ("OgmFilter.process", ogmf.process, dict(odom=np.zeros(3), angles=angles, ranges=ranges, laser_offset=np.zeros(3))),
        ("OgmFilter.ancestor_means", ogmf.ancestor_means, dict(max_lag=1, proposal_means=False)),
        ("OccupancyLattice", n.OccupancyLattice, dict(probabilities=np.full((5, 5), 0.3), resolution=0.2, origin=(0.0, 0.0))),
        ("OccupancyLattice.to_crm", lat.to_crm, dict(n_levels=10)),
        ("GpVarianceMap", n.GpVarianceMap, dict(lattice=lat, prior_variance=1.0)),
        ("InfoFunction.crmi", n.InfoFunction.crmi, dict(model=sm, n_beams=10, lambda_z=0.1, resolution=0.2)),
        (
            "InfoFunction.ucrmi",
            n.InfoFunction.ucrmi,
            dict(model=sm, weight_model=sm, alpha=0.5, n_particles=10, n_beams=10, root_cov_diag=(0.01, 0.01, 0.01)),
        ),
        ("InfoFunction.fsmi", n.InfoFunction.fsmi, dict(sigma=0.05, z_max=5.0, n_beams=10, points_per_cell=16)),
        ("InfoFunction.iig_mi", n.InfoFunction.iig_mi, dict(n_beams=10, z_max=5.0, p_occ=0.65, int_res=0.5)),
        ("InfoFunction.gpvr", n.InfoFunction.gpvr, dict(mode="reference")),
        ("InfoFunction.evaluate[crmi]", crmi.evaluate, dict(state=crm, pose=np.array([1.0, 1.0, 0.0]), seed=0)),
        ("InfoFunction.evaluate[fsmi]", fsmi.evaluate, dict(state=lat.copy(), pose=np.array([1.0, 1.0, 0.0]), seed=0)),
        ("InfoFunction.evaluate[ucrmi]", ucrmi.evaluate, dict(state=crm, pose=np.array([1.0, 1.0, 0.0]), seed=0)),
        ("InfoFunction.gains[crmi]", crmi.gains, dict(state=crm, poses=np.array([[1.0, 1.0, 0.0]]), seed=0)),
        ("InfoFunction.gains[fsmi]", fsmi.gains, dict(state=lat, poses=np.array([[1.0, 1.0, 0.0]]), seed=0)),
        ("InfoFunction.root_belief", ucrmi.root_belief, dict(pose=np.array([1.0, 1.0, 0.0]), seed=0)),
        ("InfoFunction.commit", crmi.commit, dict(state=crm.copy(), update=upd)),
        (
            "ParticleBelief.from_particles",
            n.ParticleBelief.from_particles,
            dict(particles=np.zeros((3, 3)), log_weights=np.zeros(3), entropy_nats=0.0),
        ),
        (
            "mode_seeking_pose",
            n.mode_seeking_pose,
            dict(poses=np.zeros((3, 3)), weights=np.full(3, 1 / 3), bandwidth=(0.05, 0.025)),
        ),
        ("candidate_seed", n.candidate_seed, dict(seed=1, index=2)),
        ("traverse_ray", n.traverse_ray, dict(origin_x=0.0, origin_y=0.0, angle=0.3, length=5.0, resolution=0.2)),
        (
            "cast_ranges",
            n.cast_ranges,
            dict(
                occupied=occ,
                origin_x=0.0,
                origin_y=0.0,
                resolution=0.2,
                poses=np.array([[1.0, 1.0, 0.0]]),
                angles=angles,
                max_range=5.0,
            ),
        ),
        (
            "crm_update_ray",
            n.crm_update_ray,
            dict(beliefs=np.full((2, 10), 0.1), levels=np.linspace(0.05, 0.95, 10), like=np.ones(2), like_inf=0.5),
        ),
        ("geodesic", n.geodesic, dict(traversable=np.ones((5, 5), dtype=bool), start=(1, 1), res=0.2)),
        (
            "run_iig",
            n.run_iig,
            dict(function=n.InfoFunction.gpvr(), state=gp.copy(), lattice=lat, obstacle_points=pos, options=iig_opts, seed=0),
        ),
        (
            "run_iig[options]",
            lambda **kw: n.run_iig(n.InfoFunction.gpvr(), gp.copy(), lat, pos, options={**iig_opts, **kw}),
            dict(iig_opts, budget=10.0, r_near=1.0, clearance=0.1, delta_ric=0.01, ric_window=5, sample_threshold=0.5),
        ),
        ("ParticleBelief.mean_pose", belief.mean_pose, {}),
        ("LocalMapMatcher", n.LocalMapMatcher, dict(resolution=0.05, usable_range=8.0, iterations=5, beam_stride=1)),
        (
            "LocalMapMatcher.insert",
            matcher.insert,
            dict(pose=np.zeros(3), angles=angles, ranges=ranges, laser_offset=np.zeros(3)),
        ),
        (
            "LocalMapMatcher.match_scan",
            matcher.match_scan,
            dict(start=np.zeros(3), angles=angles, ranges=ranges, laser_offset=np.zeros(3)),
        ),
    ]


def _python_specs() -> list[tuple[str, Callable[..., Any], dict[str, Any]]]:
    """Main entry points of the Python API (computations on in-memory arguments)."""
    from crlam.eval.trajectory import reference_errors
    from crlam.info import make_function
    from crlam.info.prior import lattice_from_obstacles
    from crlam.limits import set_limits
    from crlam.mapping import ConfidenceRichMap, LogOddsOccupancyMap, MappingConfig
    from crlam.planner import IigSettings
    from crlam.pose import compose, inverse, transform_points, wrap_angle
    from crlam.sim.world import World
    from crlam.slam import SlamConfig, make_filter, mode_seeking_pose

    crm = ConfidenceRichMap(MappingConfig())
    angles, ranges = np.linspace(-1, 1, 20), np.full(20, 3.0)
    occ = np.zeros((20, 20), dtype=bool)
    return [
        ("MappingConfig", MappingConfig, dict(resolution=0.2, max_range=8.0, n_levels=10, beam_stride=1, extent=None)),
        ("ConfidenceRichMap.update", crm.copy().update, dict(pose=np.zeros(3), angles=angles, ranges=ranges)),
        ("ConfidenceRichMap.layers", crm.layers, dict(bounds=(0.0, 0.0, 1.0, 1.0))),
        ("ConfidenceRichMap.log_likelihood", crm.log_likelihood, dict(pose=np.zeros(3), angles=angles, ranges=ranges)),
        ("LogOddsOccupancyMap.update", LogOddsOccupancyMap().update, dict(pose=np.zeros(3), angles=angles, ranges=ranges)),
        ("SlamConfig", SlamConfig, dict(particles=3, resolution=0.2, seed=0)),
        ("compose", compose, dict(a=np.zeros(3), b=np.zeros(3))),
        ("inverse", inverse, dict(a=np.zeros(3))),
        ("transform_points", transform_points, dict(pose=np.zeros(3), points=np.zeros((2, 2)))),
        ("wrap_angle", wrap_angle, dict(theta=1.0)),
        ("make_filter", make_filter, dict(config=SlamConfig(particles=3), initial_pose=np.zeros(3))),
        (
            "mode_seeking_pose",
            mode_seeking_pose,
            dict(poses=np.zeros((3, 3)), weights=np.full(3, 1 / 3), bandwidth=(0.05, 0.025)),
        ),
        ("make_function", make_function, dict(name="crmi", z_max=5.0, resolution=0.2, n_beams=10, n_particles=10, alpha=0.5)),
        (
            "lattice_from_obstacles",
            lattice_from_obstacles,
            dict(obstacle=occ, unknown=None, resolution=0.2, node_origin=(0.0, 0.0), margin=1.0),
        ),
        ("IigSettings", IigSettings, dict(start=(1.0, 1.0), max_wall_seconds=5.0)),
        ("World", World, dict(occupied=occ, resolution=0.2, origin=np.zeros(2), name="w")),
        (
            "reference_errors",
            reference_errors,
            dict(stamps_est=np.arange(3.0), poses_est=np.zeros((3, 3)), stamps_ref=np.arange(3.0), poses_ref=np.zeros((3, 3))),
        ),
        ("set_limits", lambda **kw: set_limits(**kw) and set_limits(map_cells=16_000_000), dict(map_cells=16_000_000)),
    ]


def _reader_specs(tmp: Path) -> list[tuple[str, Callable[..., Any], dict[str, Any]]]:
    """File readers, given hostile paths (missing, a folder, a device, empty, garbage, absurd names)."""
    from crlam.eval.trajectory import index_scans
    from crlam.info import load_map_prior
    from crlam.io import read_nav2_map, read_pgm, read_relations, read_tum
    from crlam.io.belief import load_belief
    from crlam.io.logs import open_log, read_records
    from crlam.planner import IigTree
    from crlam.sim.world import World
    from crlam.slam.presets import load_config_file

    good = tmp / "good.log"
    good.write_text("ODOM 0 0 0 0 0 0 1.0 h 1.0\n")
    return [
        ("read_records", lambda path: list(read_records(path)), dict(path=good)),
        ("open_log", lambda path: list(open_log(path)), dict(path=good)),
        ("index_scans", index_scans, dict(path=good)),
        ("read_tum", read_tum, dict(path=good)),
        ("read_relations", read_relations, dict(path=good)),
        ("read_nav2_map", read_nav2_map, dict(yaml_path=good)),
        ("read_pgm", read_pgm, dict(path=good)),
        ("load_belief", load_belief, dict(path=good)),
        ("IigTree.load", IigTree.load, dict(path=good)),
        ("load_map_prior", load_map_prior, dict(path=good)),
        ("World.from_image", World.from_image, dict(path=good, resolution=0.2)),
        ("World.from_nav2_yaml", World.from_nav2_yaml, dict(path=good)),
        ("load_config_file", load_config_file, dict(path=good)),
    ]


def _hostile_paths(tmp: Path) -> list[Any]:
    (tmp / "empty").write_bytes(b"")
    (tmp / "garbage").write_bytes(bytes(range(256)) * 64)
    (tmp / "folder").mkdir(exist_ok=True)
    paths: list[Any] = [tmp / "missing", tmp / "folder", tmp / "empty", tmp / "garbage", "a\0b", "x" * 5000, None, 3.5]
    if Path("/dev/zero").exists():
        paths.append("/dev/zero")
    return paths


def sweep(tmp: Path) -> dict[str, Any]:
    from crlam.errors import CrlamError

    calls, failures = 0, []
    plan = [(n, f, v, HOSTILE, ALLOWED) for n, f, v in _specs() + _python_specs()]
    plan += [(n, f, v, _hostile_paths(tmp), (*ALLOWED, OSError)) for n, f, v in _reader_specs(tmp)]
    for name, fn, valid, hostile, allowed in plan:
        try:
            fn(**valid)
        except Exception as e:  # noqa: BLE001 - reported
            if not valid or not isinstance(e, (CrlamError, *allowed)) or hostile is HOSTILE:
                failures.append(f"{name}(valid arguments): {type(e).__name__}: {e}")
                continue
        calls += 1
        for param in valid:
            for value in hostile:
                args = {**valid, param: value}
                calls += 1
                try:
                    fn(**args)
                except (CrlamError, *allowed):
                    pass
                except BaseException as e:  # noqa: BLE001 - PanicException derives from BaseException
                    if isinstance(e, KeyboardInterrupt):
                        raise
                    tb = traceback.format_exc(limit=-2).strip().splitlines()[-1]
                    failures.append(f"{name}({param}={_short(value)}): {type(e).__name__}: {str(e)[:200]} [{tb[:200]}]")
    return {"calls": calls, "failures": failures}


def _short(v: Any) -> str:
    if isinstance(v, np.ndarray):
        return f"array{v.shape}{v.dtype}"
    text = repr(v)
    return text if len(text) < 40 else text[:37] + "..."


if __name__ == "__main__":
    if len(sys.argv) > 1:
        import resource

        limit = int(sys.argv[1])
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        print(json.dumps(sweep(Path(d))))
