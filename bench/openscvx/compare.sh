#!/usr/bin/env bash
# One run: `armature demo` (cold process, whole pipeline: IK guess, SCvx, dense propagation,
# JSON) against OpenSCvx 0.5.2 on the same seed problem (the tutorial's script,
# seed_pick_and_place.py next to this file).
#
#   bash bench/openscvx/compare.sh [PYTHON]
#
# PYTHON (default python3) must have `openscvx==0.5.2 jaxlie` installed, e.g.
#   python3 -m venv /tmp/oxenv && /tmp/oxenv/bin/pip install openscvx==0.5.2 jaxlie
#   bash bench/openscvx/compare.sh /tmp/oxenv/bin/python
set -euo pipefail
cd "$(dirname "$0")/../.."
python=${1:-python3}
cargo build --release --locked -q -p armature-cli
out=$(mktemp -d)
echo "== armature demo (cold process, 5 runs)"
for i in 1 2 3 4 5; do
    start=$(date +%s.%N)
    ./target/release/armature demo -q -o "$out/result.json"
    end=$(date +%s.%N)
    echo "  run $i: $(echo "$end - $start" | bc) s"
done
"$python" - "$out/result.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"  status {r['status']}, {r['iterations']} iterations, final time {r['final_time']:.4f} s, "
      f"largest violation {r['max_violation']['value']:.2e} ({r['max_violation']['constraint']})")
PY
echo "== OpenSCvx 0.5.2 (cold process)"
start=$(date +%s.%N)
"$python" bench/openscvx/seed_pick_and_place.py 2>&1 | grep -E "^openscvx 0.5.2|^  " || true
end=$(date +%s.%N)
echo "  wall: $(echo "$end - $start" | bc) s"
rm -rf "$out"
