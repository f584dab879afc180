#!/usr/bin/env bash
# A unit's users' path, on the real binary: simulate config/sim-imu.toml -> characterize its six
# members -> unit -> compensate another run (simulate --seed) with the six outputs solved together
# -> export imucal, kalibr and json (unit.json against tests/schema/unit.schema.json, each member
# against model.schema.json), and c in double and float with test vectors from the held-out run
# (compiled as C99 with warnings as errors, checked by tests/unit/compensate/c_joint_driver.c).
#   unit_export_round_trip.sh BINARY_DIR SOURCE_DIR PYTHON3
set -euo pipefail
bin="$1/bin/inertia-analyze"
src="$2"
python="$3"
out="$(mktemp -d "${TMPDIR:-/tmp}/inertia-unit-export-XXXXXX")"
trap 'rm -rf "$out"' EXIT
members="ax ay az gx gy gz"

"$bin" simulate --bench "$src/config/sim-imu.toml" --out "$out/data" > /dev/null
models=()
for s in $members; do
  "$bin" characterize --dataset "$out/data/$s" --out "$out/char/$s" --jobs 1 > /dev/null
  models+=(--model "$out/char/$s/model.toml")
done
"$bin" unit "${models[@]}" --out "$out/unit" | tee "$out/unit.txt"
grep -q "Student's t on" "$out/unit.txt"
"$bin" simulate --bench "$src/config/sim-imu.toml" --seed 5 --out "$out/held" > /dev/null
"$bin" compensate --model "$out/unit/unit.toml" --dataset "$out/held" --out "$out/compensated.csv" | tee "$out/compensate.txt"
grep -q '0 without a root' "$out/compensate.txt"
head -1 "$out/compensated.csv" | grep -q '^case,t,y_ax,y_ay,y_az,y_gx,y_gy,y_gz,a_x,a_y,a_z,w_x,w_y,w_z,'

"$bin" export --model "$out/unit/unit.toml" --format imucal --out "$out/imucal"
cmp "$out/imucal/imucal.json" "$out/unit/imucal.json"
"$bin" export --model "$out/unit/unit.toml" --format kalibr --out "$out/kalibr"
grep -q '^  model: scale-misalignment' "$out/kalibr/imu.yaml"
grep -q '^    C_gyro_i: ' "$out/kalibr/imu.yaml"
"$bin" export --model "$out/unit/unit.toml" --format json --out "$out/json"
"$python" "$src/tests/schema/validate_json.py" "$src/tests/schema/unit.schema.json" "$out/json/unit.json"
"$python" - "$out/json/unit.json" "$out/json" <<'PY'
import json, sys
unit = json.load(open(sys.argv[1]))
for i, member in enumerate(unit["members"]):
    json.dump(member, open(f"{sys.argv[2]}/member-{i}.json", "w"))
PY
for f in "$out"/json/member-*.json; do
  "$python" "$src/tests/schema/validate_json.py" "$src/tests/schema/model.schema.json" "$f"
done
for precision in double float; do
  tolerance=1e-12
  [ "$precision" = float ] && tolerance=1e-6
  "$bin" export --model "$out/unit/unit.toml" --format c --precision "$precision" --prefix model \
    --vectors "$out/held" --vector-samples 5000 --out "$out/c-$precision"
  cc -std=c99 -pedantic -Wall -Wextra -Werror -O2 -I "$out/c-$precision" "$out/c-$precision/model.c" \
    "$src/tests/unit/compensate/c_joint_driver.c" -lm -o "$out/c-$precision/driver"
  # floor: 1 % of a characterized span (2 g; 3 rad/s)
  "$out/c-$precision/driver" "$out/c-$precision/model_vectors.csv" "$tolerance" 0.2
done
echo "unit round trip: unit written, held-out run compensated, imucal and kalibr written, unit.json valid, C (double and float) agrees with its vectors"
