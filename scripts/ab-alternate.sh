#!/usr/bin/env bash
# Two openrt binaries' frame times from alternating runs on one core: A, B,
# A, B, ... each playing the same frames with one thread, then the least,
# 10% and 25% quantiles of all frame times of each side and their ratios
# B / A. When the machine's other tenant swings side-by-side rounds
# (scripts/ab-frames.sh) by more than the change measured, the low
# quantiles still agree run to run: a frame is only ever slowed down by a
# neighbour, so the fastest frames of each side show the code. A binary
# against a copy of itself: 0.990-1.010 (kitchen GL-like 401..406, 8 runs).
#
#   scripts/ab-alternate.sh SCENE MODE FRAMES RUNS BIN_A BIN_B
#   scripts/ab-alternate.sh kitchen gl 401..406 8 /tmp/old/openrt target/release/openrt
#
# MODE is gl or whitted; FRAMES a range as `openrt play --frames` takes it
# (start after the first frame of a scene: it builds the trees). Any frame
# whose PNG differs between A and B is named (DIFF). Needs `taskset`.
# OPENRT_AB_ARGS: more `openrt play` options for both sides (`--accel bvh`).
set -euo pipefail
if [ $# -ne 6 ]; then
    sed -n '2,18p' "$0"
    exit 2
fi
scene=$1 mode=$2 frames=$3 runs=$4 a=$5 b=$6
cd "$(dirname "$0")/.."
case $scene in
    */*|*.ron) path=$scene ;;
    *) path=scenes/$scene.ron ;;
esac
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for r in $(seq "$runs"); do
    for side in a b; do
        bin=$a
        [ $side = b ] && bin=$b
        out="$tmp/$side-$r"
        mkdir -p "$out"
        # shellcheck disable=SC2086 # the options split into words
        if ! taskset -c 0 "$bin" play "$path" --frames "$frames" --mode "$mode" --threads 1 ${OPENRT_AB_ARGS:-} \
            --width 640 --height 480 -o "$out" --stats "$out/stats.jsonl" > "$out/log" 2>&1; then
            echo "ab-alternate: $bin failed:" >&2
            tail -3 "$out/log" >&2
            exit 1
        fi
    done
    for f in "$tmp/a-$r"/*.png; do
        cmp -s "$f" "$tmp/b-$r/$(basename "$f")" || echo "DIFF run $r $(basename "$f")"
    done
done
python3 - "$tmp" <<'EOF'
import glob, json, sys
tmp = sys.argv[1]
def times(side):
    return sorted(json.loads(l)["render_ms"] for f in glob.glob(f"{tmp}/{side}-*/stats.jsonl") for l in open(f))
a, b = times("a"), times("b")
q = lambda v, p: v[int(len(v) * p)]
for name, v in (("A", a), ("B", b)):
    print(f"{name}: {len(v)} frames, least {v[0]:.2f} ms, q10 {q(v, 0.1):.2f}, q25 {q(v, 0.25):.2f}, median {q(v, 0.5):.2f}")
print(f"B / A: least {b[0] / a[0]:.3f}, q10 {q(b, 0.1) / q(a, 0.1):.3f}, q25 {q(b, 0.25) / q(a, 0.25):.3f}")
EOF
