#!/usr/bin/env python3
"""imucal's example Ferraris session as inertia datasets, and the two calibrations compared.

What it does
------------
`datasets CSV OUT` reads imucal's annotated example session and writes three inertia dataset
folders, OUT/acc_x, OUT/acc_y and OUT/acc_z: one per accelerometer axis of the unit, each an
ordinary single-output dataset (docs/file-formats.md, "Dataset folder") whose cases are the six
static poses. `inertia-analyze characterize` takes each folder and `inertia-analyze unit` joins
the three models (docs/unit.md).

`compare --csv CSV --unit U --published example_cal.json` sets inertia's unit calibration
(U/imucal.json, with the sd from U/unit.toml) against imucal's published one: K, R and b element by
element, and both applied to the six poses' raw samples (|calibrated specific force| - g per pose).
It also recomputes imucal's accelerometer result from the CSV (the Ferraris means of its six
poses) to check that the published file belongs to this CSV.

Where the data comes from
-------------------------
The GitHub repository mad-lab-fau/imucal (MIT licence), read at commit
8716e4c50bbb7044918b747f38b26cb0a6420910 (2025-04-25):
- example_data/annotated_session.csv: columns part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z,
  raw counts of one IMU, every row labelled with its part of the session;
- tests/snapshots/example_cal.json: imucal's calibration of that CSV (FerrarisCalibrationInfo,
  from_acc_unit "a.u."); tests/test_calibration_calculation.py computes it and asserts it;
- imucal/ferraris_calibration.py: the method and the pose labels' meaning.
Nothing of imucal is copied here: the CSV and the JSON are read from the paths given on the
command line.

Pose conventions (imucal/ferraris_calibration.py, FerrarisCalibration's docstring)
-------------------------------------------------------------------------------------
- `x_p`: the unit's positive x axis is aligned with gravity, "x-acc measures +1g"; `x_a`: the
  negative x axis, x-acc measures -1g. The same for y and z. In the CSV, x_p reads acc_x about
  +2040 counts and x_a about -2052: "aligned with gravity" means pointing up, along the specific
  force of the table's reaction.
- `x_rot`, `y_rot`, `z_rot` are hand turns (360 deg) about each axis; they are not written here.
- The expected gravity is FerrarisCalibration's `grav`, default 9.81 m/s^2, which the published
  file used (the test calls FerrarisCalibration() with no arguments). `--g` changes it here.
- The sampling rate is 204.8 Hz: tests/test_calibration_calculation.py, fixture
  example_calibration_data, sampling_rate = 204.8 for annotated_session.csv. (The 102.4 Hz of
  examples/basic_ferraris.py belongs to the other file, example_ferraris_session.csv.)

In inertia's terms (docs/unit.md): F_E's z is up and a static pose's reference specific force is
a_E = (0, 0, +g). A pose is the housing's DCM M_E^U (rows: the unit's x, y, z in F_E) that puts the
labelled axis along +z_E (or -z_E); the turn about the vertical is free (a static specific force
does not see it), so the six matrices are the housing frames of config/sim-imu-tumble.toml. Each
member's m_ec is the housing's turned to put its input axis first: x member rows (x, y, z), y
member (y, z, x), z member (z, x, y) (config::unit_axis_frame).

Python 3.11 standard library only.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import tomllib

# imucal's pose labels -> the housing's M_E^U (rows: unit axes x, y, z in F_E; z_E up).
POSES: dict[str, list[list[float]]] = {
    "x_p": [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],    # x up
    "x_a": [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],   # x down
    "y_p": [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],   # y up
    "y_a": [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]],  # y down
    "z_p": [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],   # z up
    "z_a": [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],  # z down
}
AXES = "xyz"
IMUCAL_G = 9.81          # imucal/ferraris_calibration.py, FerrarisCalibration(grav=9.81)
IMUCAL_RATE_HZ = 204.8   # tests/test_calibration_calculation.py, for annotated_session.csv
MG = 9.80665e-3          # 1 mg in m/s^2 (standard gravity / 1000)


# ------------------------------------------------------------------------------------------------
# small linear algebra (3x3, lists)

def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def matvec(a, v):
    return [sum(a[i][k] * v[k] for k in range(3)) for i in range(3)]


def det(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def inv(m):
    d = det(m)
    c = [[(m[(j + 1) % 3][(i + 1) % 3] * m[(j + 2) % 3][(i + 2) % 3]
           - m[(j + 1) % 3][(i + 2) % 3] * m[(j + 2) % 3][(i + 1) % 3]) / d for j in range(3)]
         for i in range(3)]
    return c


def dot(u, v):
    return sum(x * y for x, y in zip(u, v))


def norm(v):
    return math.sqrt(dot(v, v))


def cross(u, v):
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]


def axis_turn(axis: int):
    """T_axis: rows e_axis, e_axis+1, e_axis+2 (config::unit_axis_frame)."""
    rows = []
    for r in range(3):
        e = [0.0, 0.0, 0.0]
        e[(axis + r) % 3] = 1.0
        rows.append(e)
    return rows


def mean_sd(xs):
    n = len(xs)
    m = sum(xs) / n
    sd = math.sqrt(sum((x - m) ** 2 for x in xs) / (n - 1)) if n > 1 else 0.0
    return m, sd


# ------------------------------------------------------------------------------------------------
# the session

def read_session(path: str, kind: str = "acc") -> dict[str, list[tuple[int, list[float]]]]:
    """part -> [(sample index, [KIND_x, KIND_y, KIND_z])], in file order; KIND acc or gyr."""
    parts: dict[str, list[tuple[int, list[float]]]] = {}
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        need = {"part", "samples", f"{kind}_x", f"{kind}_y", f"{kind}_z"}
        missing = need - set(reader.fieldnames or [])
        if missing:
            sys.exit(f"{path}: missing column(s) {sorted(missing)}")
        for line, row in enumerate(reader, start=2):
            try:
                k = int(float(row["samples"]))
                acc = [float(row[f"{kind}_x"]), float(row[f"{kind}_y"]), float(row[f"{kind}_z"])]
            except ValueError as e:
                sys.exit(f"{path}:{line}: {e}")
            parts.setdefault(row["part"], []).append((k, acc))
    for p in POSES:
        if p not in parts:
            sys.exit(f"{path}: no rows labelled {p}")
        ks = [k for k, _ in parts[p]]
        if any(b - a != 1 for a, b in zip(ks, ks[1:])):
            sys.exit(f"{path}: the samples of part {p} are not consecutive")
    return parts


def write_datasets(args) -> None:
    parts = read_session(args.csv)
    g = args.g
    for name, m in POSES.items():
        if abs(det(m) - 1.0) > 1e-12:
            sys.exit(f"internal: pose {name} is not a rotation")
    for axis in range(3):
        sensor = f"acc_{AXES[axis]}"
        folder = os.path.join(args.out, sensor)
        os.makedirs(folder, exist_ok=True)
        turn = axis_turn(axis)
        toml = [
            "# imucal's example Ferraris session (mad-lab-fau/imucal, example_data/annotated_session.csv),",
            f"# accelerometer axis {AXES[axis]}, written by tools/imucal_session.py; g = {g!r} m/s^2,",
            f"# {args.rate!r} Hz, temperature not recorded (written as t_ref).",
            'sensor = "accelerometer"',
            f'sensor_name = "{sensor}"',
            f'serial = "{args.serial}"',
            f'unit = "{args.unit}"',
            f'unit_axis = "{AXES[axis]}"',
            'output_unit = "counts"',
            f"t_ref = {args.t_ref!r}",
        ]
        for pose, m_eu in POSES.items():
            m_ec = matmul(turn, m_eu)
            rows = ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in m_ec)
            toml += ["", "[[case]]", f'name = "{pose}"', 'kind = "static"', f'file = "{pose}.csv"',
                     f"m_ec = [{rows}]"]
            with open(os.path.join(folder, f"{pose}.csv"), "w", newline="") as f:
                f.write("t,a_x,a_y,a_z,w_x,w_y,w_z,temp,y,phase\n")
                for k, acc in parts[pose]:
                    f.write(f"{k / args.rate!r},0,0,{g!r},0,0,0,{args.t_ref!r},{acc[axis]!r},static\n")
        with open(os.path.join(folder, "dataset.toml"), "w") as f:
            f.write("\n".join(toml) + "\n")
        print(f"wrote {folder}: 6 static cases, "
              + ", ".join(f"{p} {len(parts[p])}" for p in POSES) + " samples")


# ------------------------------------------------------------------------------------------------
# the comparison

def load_cal(path: str):
    with open(path) as f:
        d = json.load(f)
    k = [d["K_a"][i][i] for i in range(3)]
    return {"K": k, "K_a": d["K_a"], "R": d["R_a"], "b": d["b_a"], "raw": d}


def calibrate(cal, raw):
    m = matmul(inv(cal["R"]), inv(cal["K_a"]))
    return matvec(m, [raw[i] - cal["b"][i] for i in range(3)])


def ferraris_from_csv(parts, g):
    """The Ferraris accelerometer equations (means of the six poses) recomputed from the CSV."""
    mean = {p: [sum(a[i] for _, a in parts[p]) / len(parts[p]) for i in range(3)] for p in POSES}
    b = [(mean[f"{AXES[i]}_p"][i] + mean[f"{AXES[i]}_a"][i]) / 2 for i in range(3)]
    ud = [[mean[f"{AXES[j]}_p"][i] - mean[f"{AXES[j]}_a"][i] for j in range(3)] for i in range(3)]
    k = [norm(ud[i]) / (2 * g) for i in range(3)]
    r = [[ud[i][j] / (2 * g * k[i]) for j in range(3)] for i in range(3)]
    return k, r, b


def nonorth(r):
    """asin(n_j . n_k) for xy, yz, zx, with rows normalised."""
    n = [[x / norm(row) for x in row] for row in r]
    return [math.asin(dot(n[0], n[1])), math.asin(dot(n[1], n[2])), math.asin(dot(n[2], n[0]))]


def row_cov(s, cov):
    """Covariance of r = s/|s| from that of s (delta method): J C J', J = (I - r r')/|s|."""
    ns = norm(s)
    r = [x / ns for x in s]
    j = [[((1.0 if a == b else 0.0) - r[a] * r[b]) / ns for b in range(3)] for a in range(3)]
    jc = matmul(j, cov)
    return [[sum(jc[a][k] * j[c][k] for k in range(3)) for c in range(3)] for a in range(3)]


def compare(args) -> None:
    ours = load_cal(os.path.join(args.unit, "imucal.json"))
    pub = load_cal(args.published)
    with open(os.path.join(args.unit, "unit.toml"), "rb") as f:
        unit = tomllib.load(f)["accelerometer"]
    parts = read_session(args.csv)
    g = args.g
    out = []
    say = out.append

    k_sd = unit["K_sd"]
    b_sd = unit["b_sd"]
    sens = [unit["axis"][a]["sensitivity"] for a in AXES]
    covs = [unit["axis"][a]["covariance"] for a in AXES]
    rcov = [row_cov(sens[i], covs[i]) for i in range(3)]

    # imucal recomputed from the CSV (check that the published file belongs to this CSV)
    k_re, r_re, b_re = ferraris_from_csv(parts, args.published_g)
    dk = max(abs(k_re[i] - pub["K"][i]) / pub["K"][i] for i in range(3))
    dr = max(abs(r_re[i][j] - pub["R"][i][j]) for i in range(3) for j in range(3))
    db = max(abs(b_re[i] - pub["b"][i]) for i in range(3))
    say(f"imucal's published file recomputed from the CSV with g = {args.published_g}: "
        f"max |dK|/K {dk:.1e}, max |dR| {dr:.1e}, max |db| {db:.1e} counts")
    say("")

    say("## K (counts per m/s^2)")
    say("")
    say("| axis | inertia | sd | imucal | inertia - imucal | relative | in sd |")
    say("|---|---|---|---|---|---|---|")
    for i in range(3):
        d = ours["K"][i] - pub["K"][i]
        say(f"| {AXES[i]} | {ours['K'][i]:.4f} | {k_sd[i]:.4f} | {pub['K'][i]:.4f} | {d:+.4f} | "
            f"{d / pub['K'][i]:+.2e} | {d / k_sd[i]:+.1f} |")
    say("")

    say("## R (rows: the sensitive axes in the unit frame)")
    say("")
    say("| element | inertia | sd | imucal | inertia - imucal | in sd |")
    say("|---|---|---|---|---|---|")
    for i in range(3):
        for j in range(3):
            d = ours["R"][i][j] - pub["R"][i][j]
            sd = math.sqrt(max(rcov[i][j][j], 0.0))   # row i's covariance, element j
            insd = f"{d / sd:+.1f}" if sd > 1e-9 else "-"
            say(f"| R[{AXES[i]}][{AXES[j]}] | {ours['R'][i][j]:+.6f} | {sd:.6f} | {pub['R'][i][j]:+.6f} | "
                f"{d:+.6f} | {insd} |")
    say("")
    say("| row | angle between the rows (mrad) | our sd along that direction (mrad) | in sd |")
    say("|---|---|---|---|")
    for i in range(3):
        ro = [x / norm(ours["R"][i]) for x in ours["R"][i]]
        rp = [x / norm(pub["R"][i]) for x in pub["R"][i]]
        ang = math.atan2(norm(cross(ro, rp)), dot(ro, rp))
        # the difference's direction in the tangent plane at our row; our sd along it
        t = [rp[k] - dot(rp, ro) * ro[k] for k in range(3)]
        nt = norm(t)
        u = [x / nt for x in t] if nt > 0 else [0.0, 0.0, 0.0]
        sd = math.sqrt(max(sum(u[a] * rcov[i][a][c] * u[c] for a in range(3) for c in range(3)), 0.0))
        say(f"| {AXES[i]} | {ang * 1e3:.3f} | {sd * 1e3:.3f} | {ang / sd:.1f} |")
    say("")

    say("## Non-orthogonality, asin(n_j . n_k) (mrad)")
    say("")
    no_ours = nonorth(ours["R"])
    no_pub = nonorth(pub["R"])
    nsd = [unit["non_orthogonality"][f"{p}_sd"] for p in ("xy", "yz", "zx")]
    say("| pair | inertia | sd | imucal | inertia - imucal | in sd |")
    say("|---|---|---|---|---|---|")
    for n, p in enumerate(("xy", "yz", "zx")):
        d = no_ours[n] - no_pub[n]
        say(f"| {p} | {no_ours[n] * 1e3:+.3f} | {nsd[n] * 1e3:.3f} | {no_pub[n] * 1e3:+.3f} | "
            f"{d * 1e3:+.3f} | {d / nsd[n]:+.1f} |")
    say("")

    say("## b (counts)")
    say("")
    say("| axis | inertia | sd | imucal | inertia - imucal | in sd |")
    say("|---|---|---|---|---|---|")
    for i in range(3):
        d = ours["b"][i] - pub["b"][i]
        say(f"| {AXES[i]} | {ours['b'][i]:+.3f} | {b_sd[i]:.3f} | {pub['b'][i]:+.3f} | {d:+.3f} | "
            f"{d / b_sd[i]:+.1f} |")
    say("")

    say(f"## |calibrated specific force| - g per pose, g = {g} m/s^2 (mg = 9.80665e-3 m/s^2)")
    say("")
    say("| pose | samples | inertia mean (mg) | inertia sd (mg) | imucal mean (mg) | imucal sd (mg) |")
    say("|---|---|---|---|---|---|")
    worst = {"inertia": 0.0, "imucal": 0.0}
    for p in POSES:
        row = [p, str(len(parts[p]))]
        for label, cal in (("inertia", ours), ("imucal", pub)):
            e = [(norm(calibrate(cal, acc)) - g) / MG for _, acc in parts[p]]
            m, sd = mean_sd(e)
            worst[label] = max(worst[label], abs(m))
            row += [f"{m:+.3f}", f"{sd:.3f}"]
        say("| " + " | ".join(row) + " |")
    say("")
    say(f"largest |mean| over the poses: inertia {worst['inertia']:.3f} mg, imucal {worst['imucal']:.3f} mg "
        f"(target 0.5 mg)")
    say("")

    # The turns are the only rows neither fit used. The turned axis stays about vertical, but the
    # hand's motion is in every sample, so this is a rough look, not a test.
    say("## The hand turns (used by neither accelerometer fit; hand motion in every sample)")
    say("")
    say("| turn | samples | axis | inertia: that axis - g, mean (mg) | sd (mg) | imucal: mean (mg) | sd (mg) |")
    say("|---|---|---|---|---|---|---|")
    for i, p in enumerate(("x_rot", "y_rot", "z_rot")):
        if p not in parts:
            continue
        row = [p, str(len(parts[p])), AXES[i]]
        for cal in (ours, pub):
            e = [(calibrate(cal, acc)[i] - g) / MG for _, acc in parts[p]]
            m, sd = mean_sd(e)
            row += [f"{m:+.2f}", f"{sd:.1f}"]
        say("| " + " | ".join(row) + " |")
    text = "\n".join(out) + "\n"
    print(text, end="")
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)


def gyro_poses(args) -> None:
    """imucal's gyroscope bias and g-sensitivity (K_ga, its eq. 9: the difference of the up and
    down poses' means over 2g) recomputed from the CSV, each K_ga element with the standard error
    the poses' white noise gives it (within-pose sd / sqrt(samples), the two poses combined). The
    gyroscopes' bias drifts between poses as well, so that sd is a floor and |K_ga| / sd an upper
    bound on how many sd an element stands from zero."""
    parts = read_session(args.csv, "gyr")
    with open(args.published) as f:
        pub = json.load(f)
    g = args.published_g
    out = []
    say = out.append
    all_static = [v for p in POSES for _, v in parts[p]]
    b = [sum(v[i] for v in all_static) / len(all_static) for i in range(3)]
    say(f"b_g recomputed (mean of the six poses' samples): {', '.join(f'{x:+.4f}' for x in b)} counts; "
        f"published {', '.join(f'{x:+.4f}' for x in pub['b_g'])}")
    say("")
    say(f"| gyro | along | K_ga recomputed | white-noise sd | K_ga / sd | published K_ga |")
    say("|---|---|---|---|---|---|")
    for i in range(3):
        for j in range(3):
            up, down = parts[f"{AXES[j]}_p"], parts[f"{AXES[j]}_a"]
            mu, su = mean_sd([v[i] for _, v in up])
            md, sdn = mean_sd([v[i] for _, v in down])
            k = (mu - md) / (2 * g)
            sd = math.sqrt(su * su / len(up) + sdn * sdn / len(down)) / (2 * g)
            say(f"| {AXES[i]} | {AXES[j]} | {k:+.5f} | {sd:.5f} | {k / sd:+.1f} | {pub['K_ga'][i][j]:+.5f} |")
    text = "\n".join(out) + "\n"
    print(text, end="")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    d = sub.add_parser("datasets", help="write OUT/acc_x, OUT/acc_y, OUT/acc_z from annotated_session.csv")
    d.add_argument("csv", help="imucal's example_data/annotated_session.csv")
    d.add_argument("out", help="folder for the three dataset folders")
    d.add_argument("--g", type=float, default=IMUCAL_G,
                   help=f"specific force of a static pose, m/s^2 (default {IMUCAL_G}, imucal's grav)")
    d.add_argument("--rate", type=float, default=IMUCAL_RATE_HZ,
                   help=f"sampling rate, Hz (default {IMUCAL_RATE_HZ}, imucal's test for this file)")
    d.add_argument("--t-ref", type=float, default=25.0, help="t_ref and the constant temperature, degC")
    d.add_argument("--unit", default="imucal-example", help="the unit's name")
    d.add_argument("--serial", default="imucal-example", help="the unit's serial")
    d.set_defaults(run=write_datasets)
    c = sub.add_parser("compare", help="inertia's unit calibration against imucal's published one")
    c.add_argument("--csv", required=True, help="imucal's example_data/annotated_session.csv")
    c.add_argument("--unit", required=True, help="the folder inertia-analyze unit wrote")
    c.add_argument("--published", required=True, help="imucal's tests/snapshots/example_cal.json")
    c.add_argument("--g", type=float, default=IMUCAL_G, help="g the calibrated norms are set against")
    c.add_argument("--published-g", type=float, default=IMUCAL_G,
                   help="g imucal used for the published file (for the recomputation check)")
    c.add_argument("--out", help="also write the tables to this file")
    c.set_defaults(run=compare)
    gp = sub.add_parser("gyro-poses", help="imucal's gyroscope b_g and K_ga from the poses, with K_ga's white-noise sd")
    gp.add_argument("--csv", required=True, help="imucal's example_data/annotated_session.csv")
    gp.add_argument("--published", required=True, help="imucal's tests/snapshots/example_cal.json")
    gp.add_argument("--published-g", type=float, default=IMUCAL_G, help="g imucal used for the published file")
    gp.set_defaults(run=gyro_poses)
    args = ap.parse_args()
    args.run(args)


if __name__ == "__main__":
    main()
