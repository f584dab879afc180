#!/usr/bin/env bash
# The model file round trip and the diagnose output contract, on the real binary:
#   simulate (config/sim-tumble.toml) -> characterize -> model.toml -> diagnose --json
# The model characterize wrote must load in diagnose (and in online --model, which reads it at
# start); diagnose's JSON and the augmented model it writes must be valid: the JSON against
# tests/schema/diagnose.schema.json, the augmented model read back by diagnose once more.
#   round_trip.sh BINARY_DIR SOURCE_DIR PYTHON3
set -euo pipefail
bin="$1/bin/inertia-analyze"
src="$2"
python="$3"
out="$(mktemp -d "${TMPDIR:-/tmp}/inertia-round-trip-XXXXXX")"
trap 'rm -rf "$out"' EXIT

"$bin" simulate --bench "$src/config/sim-tumble.toml" --out "$out/dataset" > "$out/simulate.txt"
"$bin" characterize --dataset "$out/dataset" --out "$out/characterization" > "$out/characterize.txt"
test -s "$out/characterization/model.toml"
"$bin" diagnose --model "$out/characterization/model.toml" --dataset "$out/dataset" \
  --json "$out/diagnose.json" --report "$out/report" > "$out/diagnose.txt"
"$python" "$src/tests/schema/validate_json.py" "$src/tests/schema/diagnose.schema.json" "$out/diagnose.json"
# The augmented model diagnose wrote is a model file too: it loads in diagnose again.
"$bin" diagnose --model "$out/report/model-augmented.toml" --dataset "$out/dataset" \
  --json "$out/diagnose-again.json" > "$out/diagnose-again.txt"
"$python" "$src/tests/schema/validate_json.py" "$src/tests/schema/diagnose.schema.json" "$out/diagnose-again.json"
echo "round trip: characterize's model.toml loaded in diagnose, both outputs valid"
