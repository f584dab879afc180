#!/usr/bin/env bash
# What a characterized sensor's users receive, on the real binary:
#   simulate (config/sim-rotation-table.toml) -> characterize acc1 -> compensate a held-out run
#   -> export json (against tests/schema/model.schema.json), c in double and float with test
#   vectors (compiled as C99 with warnings as errors and checked against the vectors by
#   tests/unit/compensate/c_export_driver.c), kalibr (its keys present); the parameter sheet
#   characterize wrote against tests/schema/sheet.schema.json, and the sheet verb's the same.
#   export_round_trip.sh BINARY_DIR SOURCE_DIR PYTHON3
set -euo pipefail
bin="$1/bin/inertia-analyze"
src="$2"
python="$3"
out="$(mktemp -d "${TMPDIR:-/tmp}/inertia-export-XXXXXX")"
trap 'rm -rf "$out"' EXIT

"$bin" simulate --bench "$src/config/sim-rotation-table.toml" --out "$out/data" > /dev/null
"$bin" characterize --dataset "$out/data/acc1" --out "$out/char" --jobs 1 > /dev/null
sed 's/^seed = 11$/seed = 12/' "$src/config/sim-rotation-table.toml" > "$out/held.toml"
"$bin" simulate --bench "$out/held.toml" --out "$out/held" > /dev/null
"$bin" compensate --model "$out/char/model.toml" --dataset "$out/held/acc1" --out "$out/compensated.csv" | tee "$out/compensate.txt"
grep -q '0 without a root' "$out/compensate.txt"

"$bin" export --model "$out/char/model.toml" --format json --out "$out/json"
"$python" "$src/tests/schema/validate_json.py" "$src/tests/schema/model.schema.json" "$out/json/model.json"

for precision in double float; do
  tolerance=1e-12
  [ "$precision" = float ] && tolerance=1e-6
  "$bin" export --model "$out/char/model.toml" --format c --precision "$precision" --prefix model \
    --vectors "$out/held/acc1" --vector-samples 20000 --out "$out/c-$precision"
  cc -std=c99 -pedantic -Wall -Wextra -Werror -O2 -I "$out/c-$precision" "$out/c-$precision/model.c" \
    "$src/tests/unit/compensate/c_export_driver.c" -lm -o "$out/c-$precision/driver"
  # floor: 1 % of the characterized span of a_i (2 g)
  "$out/c-$precision/driver" "$out/c-$precision/model_vectors.csv" "$tolerance" 0.2
done

# characterize wrote the parameter sheet beside the model; the sheet verb writes it from the model alone.
"$python" "$src/tests/schema/validate_json.py" "$src/tests/schema/sheet.schema.json" "$out/char/sheet.json"
"$bin" sheet --model "$out/char/model.toml" --out "$out/sheet"
cmp "$out/char/sheet.json" "$out/sheet/sheet.json"
grep -q '<table>' "$out/sheet/sheet.html"

"$bin" export --model "$out/char/model.toml" --format kalibr --out "$out/kalibr"
grep -q '^accelerometer_noise_density: ' "$out/kalibr/imu.yaml"
grep -q '^update_rate: 1000' "$out/kalibr/imu.yaml"
grep -q 'left out' "$out/kalibr/imu.yaml"
cat "$out/kalibr/imu.yaml"
echo "export round trip: compensate, json valid, C (double and float) agrees with its vectors, kalibr written"
