"""Writes the corpus of damaged and hostile ROS bags of this folder (``python make_corpus.py``).

Every file is made from the small synthetic bags of the ROS bag tests (``tests/test_io_rosbag.py``:
10 scans of 9 beams, 41 odometry readings), damaged the way a robot's disk, a copy or a tool
damages them, or written with the hostile values of a faulty driver. ``corpus.json`` says what
crlam must do with each: ``error`` (a :class:`crlam.errors.CrlamError` whose message holds
``match``) or ``skip`` (the bag reads, with the named counter of skipped messages). The corpus is
generated, deterministic (random bytes from a fixed seed) and a few hundred KB; the test is
``tests/test_bag_reliability.py``.
"""

from __future__ import annotations

import json
import math
import random
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from bag_messages import write_mutated  # noqa: E402
from test_io_rosbag import BagSpec, write_bag  # noqa: E402

#: name -> (expected outcome, text the error holds or the counter that is nonzero)
EXPECTED: dict[str, dict[str, str]] = {}


def expect(name: str, outcome: str, match: str) -> None:
    EXPECTED[name] = {"expect": outcome, "match": match}


def _metadata_variant(src: Path, name: str, edit: Callable[[str], str], match: str) -> None:
    dst = HERE / name
    shutil.copytree(src, dst)
    meta = dst / "metadata.yaml"
    meta.write_text(edit(meta.read_text()))
    expect(name, "error", match)


def main() -> None:
    for p in HERE.iterdir():
        if p.name not in ("make_corpus.py", "corpus.json", "__pycache__"):
            shutil.rmtree(p) if p.is_dir() else p.unlink()
    work = HERE / "_work"
    work.mkdir()
    spec = BagSpec(n_scans=4)
    # Messages up to 100.8 s: 17 odometry readings and the 4 scans (small files).
    until = 100.8
    mcap_folder = write_mutated(work / "m", spec, folder=True, until=until)
    sqlite_folder = write_mutated(work / "s", spec, storage="sqlite3", folder=True, until=until)
    ros1 = write_bag(work / "r", spec, "ros1")
    (mcap_file,) = mcap_folder.glob("*.mcap")
    (db3,) = sqlite_folder.glob("*.db3")
    rng = random.Random(49)

    # Files cut short, emptied, of garbage or of text.
    data = mcap_file.read_bytes()
    (HERE / "truncated.mcap").write_bytes(data[: len(data) // 2])
    expect("truncated.mcap", "error", "truncated.mcap")
    data = ros1.read_bytes()
    (HERE / "truncated.bag").write_bytes(data[: len(data) * 2 // 3])
    expect("truncated.bag", "error", "truncated.bag")
    (HERE / "sqlite-truncated").mkdir()
    shutil.copy(sqlite_folder / "metadata.yaml", HERE / "sqlite-truncated")
    (HERE / "sqlite-truncated" / db3.name).write_bytes(db3.read_bytes()[:6000])
    expect("sqlite-truncated", "error", "sqlite-truncated")
    (HERE / "empty.bag").write_bytes(b"")
    expect("empty.bag", "error", "empty.bag")
    (HERE / "empty.mcap").write_bytes(b"")
    expect("empty.mcap", "error", "empty.mcap")
    (HERE / "garbage.bag").write_bytes(bytes(rng.randrange(256) for _ in range(4096)))
    expect("garbage.bag", "error", "garbage.bag")
    (HERE / "text.mcap").write_text("This is not a bag.\n" * 50)
    expect("text.mcap", "error", "text.mcap")
    flipped = bytearray(mcap_file.read_bytes())
    for _ in range(40):
        i = rng.randrange(64, len(flipped) - 64)
        flipped[i] ^= 0xFF
    (HERE / "flipped.mcap").write_bytes(bytes(flipped))
    expect("flipped.mcap", "error", "flipped.mcap")

    # A zstd-compressed bag whose compressed file is damaged, and a bag that claims compression.
    zdir = write_mutated(work / "z", spec, folder=True, until=until, zstd=True)
    shutil.copytree(zdir, HERE / "zstd-corrupt")
    (zst,) = (HERE / "zstd-corrupt").glob("*.zstd")
    z = bytearray(zst.read_bytes())
    for i in range(len(z) // 3, len(z) // 3 + 64):
        z[i] ^= 0x5A
    zst.write_bytes(bytes(z))
    expect("zstd-corrupt", "error", "zstd")
    _metadata_variant(
        mcap_folder,
        "compression-lie",
        lambda t: t.replace("compression_format: ''", "compression_format: zstd").replace(
            "compression_mode: ''", "compression_mode: FILE"
        ),
        "compression-lie",
    )

    # metadata.yaml that lies (on the zstd-compressed bag: a small file, read by none of them).
    name = next(zdir.glob("*.zstd")).name
    _metadata_variant(zdir, "metadata-missing-file", lambda t: t.replace(name, "gone.mcap.zstd"), "missing")
    _metadata_variant(
        zdir,
        "metadata-storage-unknown",
        lambda t: t.replace("storage_identifier: mcap", "storage_identifier: rosbag_v9"),
        "storage",
    )
    _metadata_variant(zdir, "metadata-version-99", lambda t: t.replace("version: 9", "version: 99"), "version")
    _metadata_variant(zdir, "metadata-not-yaml", lambda t: "rosbag2_bagfile_information: [\n  {: : :\n", "invalid YAML")
    _metadata_variant(zdir, "metadata-list", lambda t: "- 1\n- 2\n", "rosbag2_bagfile_information")
    _metadata_variant(zdir, "metadata-null", lambda t: "null\n", "rosbag2_bagfile_information")
    _metadata_variant(zdir, "metadata-nested", lambda t: "a: " + "[" * 5000 + "]" * 5000 + "\n", "nested")
    _metadata_variant(zdir, "metadata-escape", lambda t: t.replace(f"- {name}", "- ../../etc/passwd"), "outside")
    _metadata_variant(zdir, "metadata-absolute", lambda t: t.replace(f"- {name}", "- /etc/passwd"), "outside")
    _metadata_variant(
        mcap_folder,
        "metadata-ros1-serialisation",
        lambda t: t.replace("serialization_format: cdr", "serialization_format: ros1"),
        "metadata-ros1-serialisation",
    )

    # Messages a faulty driver writes (plain .mcap files).
    def scan_field(field: str, value: float) -> Callable[[str, Any], Any]:
        def edit(topic: str, msg: Any) -> Any:
            if topic == "/scan":
                setattr(msg, field, value)
            return msg

        return edit

    def odom_quaternion(scale: float) -> Callable[[str, Any], Any]:
        def edit(topic: str, msg: Any) -> Any:
            if topic == "/odom":
                q = msg.pose.pose.orientation
                q.x, q.y, q.z, q.w = q.x * scale, q.y * scale, q.z * scale, q.w * scale
            return msg

        return edit

    def nan_mount(topic: str, msg: Any) -> Any:
        if topic == "/tf_static":
            msg.transforms[0].transform.translation.x = math.nan
        return msg

    mounted = BagSpec(n_scans=4, static=[("base_link", "laser", (0.1, 0.0, 0.2), (0.0, 0.0, 0.0))])
    for name, bag_spec, edit, outcome, match in [
        ("scan-range-max-nan.mcap", spec, scan_field("range_max", math.nan), "error", "range_max"),
        ("scan-angle-increment-nan.mcap", spec, scan_field("angle_increment", math.nan), "error", "angle_increment"),
        ("scan-range-min-negative.mcap", spec, scan_field("range_min", -1.0), "error", "range_min"),
        ("scan-time-increment-inf.mcap", spec, scan_field("time_increment", math.inf), "error", "time_increment"),
        ("odom-quaternion-zero.mcap", spec, odom_quaternion(0.0), "error", "quaternion"),
        ("odom-quaternion-doubled.mcap", spec, odom_quaternion(2.0), "error", "length 2"),
        ("tf-static-nan-mount.mcap", mounted, nan_mount, "error", "translation"),
    ]:
        write_mutated(HERE / name, bag_spec, edit, until=until)
        expect(name, outcome, match)

    def stamps_back(topic: str, msg: Any) -> Any:
        # The third scan stamped 1 s before the second, the fourth at the second's stamp.
        if topic == "/scan" and msg.header.stamp.sec == 100 and msg.header.stamp.nanosec in (510_000_000, 710_000_000):
            if msg.header.stamp.nanosec == 510_000_000:
                msg.header.stamp.sec = 99
            else:
                msg.header.stamp.nanosec = 310_000_000
        return msg

    write_mutated(HERE / "scan-stamps-backwards.mcap", spec, stamps_back, until=until)
    expect("scan-stamps-backwards.mcap", "skip", "skipped_stamp_backwards,skipped_stamp_repeated")

    shutil.rmtree(work)
    (HERE / "corpus.json").write_text(json.dumps(EXPECTED, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
