#!/usr/bin/env python3
"""characterize's cost against the record's length: the paper plan with every phase k times longer.

For each scale k: the bench file with every phase's duration_s multiplied by k is simulated into a
dataset (`inertia-analyze simulate`), then `inertia-analyze characterize --dataset` runs under
GNU time. Printed per scale: the dataset's rows, characterize's wall time, its peak resident set,
rows per second, and each ratio against the first scale (time ratio / row ratio is 1 for a cost
linear in the record). The figures of a run go to docs/validation.md with the machine and date;
CI runs the small scales (1 and 4) so that the script keeps working.

Exit status 1 when a step fails; the figures themselves are measurements, not tests.

usage: tests/bench/characterize_growth.py [--build build] [--config config/sim-paper.toml]
                                          [--scales 1,4] [--keep DIR]
"""
import argparse
import csv
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
DURATION = re.compile(r"^(\s*duration_s\s*=\s*)([0-9.eE+-]+)", re.M)


def scaled_bench(text, k):
    """The bench file with every phase's duration_s multiplied by k (ramps and pulses unchanged)."""
    count = len(DURATION.findall(text))
    if count == 0:
        sys.exit("characterize_growth: the bench file has no duration_s to scale")
    return DURATION.sub(lambda m: f"{m.group(1)}{float(m.group(2)) * k!r}", text)


def dataset_rows(folder):
    """Rows of every case file of the dataset (the CSVs beside dataset.toml, header excluded; the
    references/ folder holds the same rows' references)."""
    rows = 0
    for f in sorted(pathlib.Path(folder).glob("*.csv")):
        with open(f) as handle:
            rows += max(0, sum(1 for _ in handle) - 1)
    return rows


def timed(args, log):
    """Runs args under GNU time -v; returns (wall s, peak RSS MB)."""
    with open(log, "w") as out:
        start = time.monotonic()
        subprocess.run(["/usr/bin/time", "-v", *map(str, args)], stdout=out, stderr=subprocess.STDOUT, check=True)
        wall = time.monotonic() - start
    peak_kb = 0
    for line in open(log):
        if "Maximum resident set size" in line:
            peak_kb = int(line.split(":")[1])
    return wall, peak_kb / 1024.0


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--build", default=str(ROOT / "build"))
    p.add_argument("--config", default=str(ROOT / "config" / "sim-paper.toml"))
    p.add_argument("--scales", default="1,4")
    p.add_argument("--keep", help="keep the datasets and logs in this folder")
    a = p.parse_args()
    analyzer = pathlib.Path(a.build) / "bin" / "inertia-analyze"
    if not shutil.which("/usr/bin/time"):
        sys.exit("characterize_growth: GNU time (/usr/bin/time, Debian package 'time') is needed for the peak RSS")
    scales = [float(s) for s in a.scales.split(",")]
    text = pathlib.Path(a.config).read_text()
    work = pathlib.Path(a.keep) if a.keep else pathlib.Path(tempfile.mkdtemp(prefix="growth-"))
    work.mkdir(parents=True, exist_ok=True)
    results = []
    try:
        for k in scales:
            d = work / f"x{k:g}"
            d.mkdir(exist_ok=True)
            bench = d / "bench.toml"
            bench.write_text(scaled_bench(text, k))
            subprocess.run([analyzer, "simulate", "--bench", bench, "--out", d / "dataset"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, check=True)
            rows = dataset_rows(d / "dataset")
            wall, rss = timed([analyzer, "characterize", "--dataset", d / "dataset", "--out", d / "out"], d / "characterize.txt")
            results.append((k, rows, wall, rss))
            print(f"x{k:g}: {rows} rows, {wall:.1f} s, {rss:.0f} MB peak, {rows / wall:.0f} rows/s", flush=True)
    except subprocess.CalledProcessError as e:
        print(f"characterize_growth: {e.cmd[0] if e.cmd else 'a step'} failed ({e.returncode}); logs in {work}")
        return 1
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)
    k0, rows0, wall0, rss0 = results[0]
    writer = csv.writer(sys.stdout)
    writer.writerow(["scale", "rows", "wall_s", "peak_rss_mb", "rows_per_s", "row_ratio", "time_ratio", "rss_ratio",
                     "time_ratio_per_row_ratio"])
    for k, rows, wall, rss in results:
        writer.writerow([f"{k:g}", rows, f"{wall:.2f}", f"{rss:.0f}", f"{rows / wall:.0f}", f"{rows / rows0:.2f}",
                         f"{wall / wall0:.2f}", f"{rss / rss0:.2f}", f"{(wall / wall0) / (rows / rows0):.2f}"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
