#!/usr/bin/env python3
"""Live against offline on the same log, bench by bench.

For each bench: the daemon plays it (--fast) into a log; `inertia-analyze online --replay` runs the
live estimator on that log to its end; `characterize --log` runs the batch procedure on it, sensor by
sensor. Printed per sensor: the terms only one of them carries, and for the terms both carry the
difference over the combined sd (z) and the ratio of their sd.

Both read the same rows, so where the rules are the same their answers are nearly equal and z is
far below 1; a term set that differs or a z near or above 1 points at a rule the two paths apply
differently. Exit status 1 when any sensor's terms differ or any |z| exceeds --max-z.

With --noise-window at least the record's length (CTest runs it with 1e9: the test
parity.live_against_characterize_every_bench), live fits its noise model at the log's end on every
row, as characterize does; with online's default window (2 s) live's noise model is fitted on the
record's first seconds, and the two whiteners alone move the estimates by up to about 1.5 combined
sd (docs/validation.md). --seed replaces the bench's simulator seed, for studies over seeds.

usage: tests/parity/live_offline_parity.py [--build build] [--max-z 1] [--noise-window S] [--seed N]
                                          [BENCH:SENSOR,SENSOR ...]
"""
import argparse
import csv
import math
import os
import pathlib
import re
import subprocess
import sys
import tempfile
import tomllib

BENCHES = [
    "sim-rotation-table:acc1,fog1",
    "sim-shaker:acc-a,acc-b",
    "sim-thermal:acc1",
    "sim-tumble:mems1",
    "sim-gyro-thermal:fog1",
]
ROOT = pathlib.Path(__file__).resolve().parents[2]


def bench_with_seed(config, seed, folder):
    """A copy of the bench file in folder with its [bench] seed replaced (the simulator's draws)."""
    text = config.read_text()
    bench = text.index("[bench]")
    head, tail = text[:bench], text[bench:]
    tail, count = re.subn(r"(?m)^seed\s*=\s*\d+", f"seed = {seed}", tail, count=1)
    if count != 1:
        sys.exit(f"{config}: no seed in its [bench] table")
    copy = folder / config.name
    copy.write_text(head + tail)
    return copy


def run(args, out):
    with open(out, "w") as f:
        subprocess.run(args, stdout=f, stderr=subprocess.STDOUT, check=True)


def last_live_rows(history):
    rows = list(csv.reader(open(history)))
    header, last = rows[0], {}
    for r in rows[1:]:
        if r and r[0]:
            last[r[0]] = r + [""] * (len(header) - len(r))
    return header, last


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--build", default=str(ROOT / "build"))
    p.add_argument("--max-z", type=float, default=1.0)
    p.add_argument("--noise-window", type=float, help="online's --noise-window (s); its default if not given")
    p.add_argument("--seed", type=int, help="the bench's simulator seed; the shipped file's if not given")
    p.add_argument("benches", nargs="*", default=BENCHES)
    a = p.parse_args()
    binary = pathlib.Path(a.build) / "bin"
    # A port of this process's own (the test harness's private ports are 20000-39999), so that no
    # test running beside it hears this daemon.
    lcm_url = f"udpm://239.255.76.67:{40000 + os.getpid() % 20000}?ttl=0"
    failed = False
    for spec in a.benches:
        bench, sensors = spec.split(":")
        config = ROOT / "config" / f"{bench}.toml"
        with tempfile.TemporaryDirectory() as tmp:
            d = pathlib.Path(tmp)
            if a.seed is not None:
                config = bench_with_seed(config, a.seed, d)
            run([binary / "inertia-daqd", "--config", config, "--fast", "--log", d / "log",
                 "--lcm-url", lcm_url], d / "daqd.txt")
            log = next((d / "log").glob("*.lcmlog"))
            window = [] if a.noise_window is None else ["--noise-window", str(a.noise_window)]
            run([binary / "inertia-analyze", "online", "--config", config, "--replay", log,
                 "--history", d / "history.csv", *window], d / "online.txt")
            header, last = last_live_rows(d / "history.csv")
            for sensor in sensors.split(","):
                run([binary / "inertia-analyze", "characterize", "--log", log, "--sensor", sensor,
                     "--out", d / sensor], d / f"{sensor}.txt")
                model = tomllib.load(open(d / sensor / "model.toml", "rb"))
                offline = {k: (v, model["std"].get(k, math.nan)) for k, v in model["terms"].items()}
                row, live = last[sensor], {}
                for c in range(5, len(header) - 1, 2):
                    if row[c] and row[c] != "nan":
                        live[header[c]] = (float(row[c]), float(row[c + 1]))
                only_live, only_offline = sorted(set(live) - set(offline)), sorted(set(offline) - set(live))
                print(f"{bench}/{sensor}: live converged {row[4] == '1'}; live only {only_live or '-'}; "
                      f"offline only {only_offline or '-'}")
                failed |= bool(only_live or only_offline)
                for term in sorted(set(live) & set(offline)):
                    (lv, ls), (ov, osd) = live[term], offline[term]
                    z = (lv - ov) / math.hypot(ls, osd)
                    failed |= not abs(z) <= a.max_z
                    print(f"  {term:10s} live {lv:+.6e} ({ls:.2e})  offline {ov:+.6e} ({osd:.2e})  "
                          f"z {z:+.2f}  sd live/offline {ls / osd:.2f}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
