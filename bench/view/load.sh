#!/usr/bin/env bash
# How big the 3D view of the seed's result is and how fast it opens: the page's size, and
# the time from navigation to its first drawn frame (the page records performance.now() at
# that frame in <body data-first-frame-ms>) in headless Chromium with software WebGL, over
# RUNS cold browser starts (default 7). Targets (issue 26): < 3 MB, < 2 s.
#
#   bash bench/view/load.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-7}
command -v chromium >/dev/null || { echo "needs chromium (apt-get install chromium)" >&2; exit 1; }
cargo build --release --locked -q -p armature-cli
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for example in pick-and-place pick-and-place-collision; do
    ./target/release/armature demo "$example" -q --html "$out/$example.html"
    bytes=$(wc -c <"$out/$example.html")
    times=()
    for i in $(seq "$runs"); do
        dom=$(chromium --headless --no-sandbox --user-data-dir="$out/profile-$i" \
            --window-size=1280,800 --dump-dom "file://$out/$example.html" 2>/dev/null)
        ms=$(grep -o 'data-first-frame-ms="[0-9.]*"' <<<"$dom" | grep -o '[0-9.]*')
        times+=("$ms")
    done
    sorted=$(printf '%s\n' "${times[@]}" | sort -g)
    median=$(sed -n "$(( (runs + 1) / 2 ))p" <<<"$sorted")
    max=$(tail -1 <<<"$sorted")
    printf '%-26s %8.2f MB   first frame: median %6.0f ms, max %6.0f ms (%d runs)\n' \
        "$example" "$(echo "$bytes / 1000000" | bc -l)" "$median" "$max" "$runs"
done
