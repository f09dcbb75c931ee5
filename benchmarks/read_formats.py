"""Benchmark: reading one recording in each format it exists in (CSV export, ROS 1 bag, rosbag2).

The same recordings in every format, in a temporary folder: a chen2017_handover demo as its CSV
export, its ROS 1 bag and that bag converted by ``rosbags``' converter (what ``rosbags-convert``
does) to rosbag2 with MCAP and with SQLite storage; a handover_20171128 demo as its
``multiModal_states.csv`` and its messages written as rosbag2 MCAP and SQLite
(``tests/helpers_rosbag2.py``, as the reader's tests write them). Every format is read
``--repeats`` times, the formats alternating within one process so that a shared machine's drift
affects all alike; prints per format the median read time (``read_demo``: decoding, alignment,
filtering, checks) in [ms] and its ratio to the CSV's of the same recording, and the first read
of a rosbag2 apart (``rosbags``' type store and generated deserialisers, cached afterwards).

    taskset -c 0 python benchmarks/read_formats.py [--datasets ../shared/datasets] [--repeats 30]

``--smoke``: the synthetic recording of ``tests/helpers_rosbag2.py`` as rosbag2 only, 3 reads:
seconds, what the test suite runs.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import helpers_rosbag2 as h  # noqa: E402  (the tests' rosbag2 writer)

from ipromp_pin.readers import read_demo  # noqa: E402

CHEN2017 = ("chen2017_handover", "tape_hold", "2017-07-11-15-45-25")
MULTIMODAL = ("handover_20171128", "tape", "2017-11-28-10-05-45")


def _chen2017(datasets: Path, tmp: Path) -> dict[str, Path]:
    from rosbags.convert.converter import convert

    name, task, stamp = CHEN2017
    folder = datasets / name / task
    out = {"CSV export": folder / "csv" / stamp, "ROS 1 bag": folder / f"{stamp}.bag"}
    for storage, label in (("mcap", "rosbag2 (MCAP)"), ("sqlite3", "rosbag2 (SQLite)")):
        dst = tmp / f"chen_{storage}"
        convert([out["ROS 1 bag"]], dst, storage, 8, None, "file", None, None, [], [], [], [])
        out[label] = dst
    return out


def _multimodal(datasets: Path, tmp: Path) -> dict[str, Path]:
    name, task, stamp = MULTIMODAL
    csv = datasets / name / task / "csv" / stamp / "multiModal_states.csv"
    records = h.multimodal_records(csv)
    out = {"multiModal_states.csv": csv}
    for storage, label in (("mcap", "rosbag2 (MCAP)"), ("sqlite3", "rosbag2 (SQLite)")):
        out[label] = h.write_rosbag2(tmp / f"mm_{storage}", records, storage)
    return out


def _time(paths: dict[str, Path], repeats: int, frames: list[str] | None) -> dict[str, list[float]]:
    """Read times [ms] per format, the formats alternating; the first read of each format apart."""
    times: dict[str, list[float]] = {k: [] for k in paths}
    for label, path in paths.items():
        t0 = time.perf_counter()
        read_demo(path, "t", frames=frames)
        times[label + " (first read)"] = [(time.perf_counter() - t0) * 1e3]
    for _ in range(repeats):
        for label, path in paths.items():
            t0 = time.perf_counter()
            read_demo(path, "t", frames=frames)
            times[label].append((time.perf_counter() - t0) * 1e3)
    return times


def _report(title: str, times: dict[str, list[float]], reference: str | None) -> None:
    print(title)
    ref = float(np.median(times[reference])) if reference else None
    for label, ms in times.items():
        med = float(np.median(ms))
        ratio = "" if ref is None or "first" in label else f"  {med / ref:.2f}x the {reference}"
        print(f"  {label:<32} {med:8.1f} ms{ratio}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--datasets", type=Path, default=ROOT.parent / "shared" / "datasets")
    ap.add_argument("--repeats", type=int, default=30, help="reads per format (default 30)")
    ap.add_argument("--smoke", action="store_true", help="the synthetic recording, 3 reads: seconds")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        if args.smoke:
            records = h.Synthetic(seed=0).records()
            paths = {
                "rosbag2 (MCAP)": h.write_rosbag2(tmp / "mcap", records, "mcap"),
                "rosbag2 (SQLite)": h.write_rosbag2(tmp / "sqlite", records, "sqlite3"),
            }
            _report("synthetic recording (3 s)", _time(paths, 3, ["/left_hand_1"]), None)
            return 0
        if not args.datasets.is_dir():
            ap.error(f"{args.datasets}: datasets folder not found (--datasets)")
        stamp = CHEN2017[2]
        _report(
            f"chen2017_handover {stamp}",
            _time(_chen2017(args.datasets, tmp), args.repeats, None),
            "CSV export",
        )
        stamp = MULTIMODAL[2]
        times = _time(_multimodal(args.datasets, tmp), args.repeats, ["/left_hand_1"])
        _report(f"handover_20171128 {stamp} (frames /left_hand_1)", times, "multiModal_states.csv")
    return 0


if __name__ == "__main__":
    sys.exit(main())
