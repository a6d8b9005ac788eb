#!/usr/bin/env bash
# Two openrt binaries' frame times, measured side by side: A and B play the
# same frames at the same time, one thread each, each pinned to its own
# core, and swap cores every round. On a shared 2-core machine whose speed
# drifts by 10-30% from one minute to the next, both sides then see the
# same drift; run one after the other, a 2-4% change is lost in it.
#
#   scripts/ab-frames.sh SCENE MODE FRAMES ROUNDS BIN_A BIN_B
#   scripts/ab-frames.sh kitchen gl 400..420 8 /tmp/old/openrt target/release/openrt
#
# MODE is gl or whitted; FRAMES a range as `openrt play --frames` takes it.
# Prints, per round, each side's median render time (ms) and B / A, then
# the median of the ratios; any frame whose PNG differs between A and B is
# named (DIFF). A binary against a copy of itself gave ratios of
# 0.989-1.020 (kitchen GL-like, six rounds): smaller changes need more
# rounds. Needs two cores and `taskset` (util-linux).
set -euo pipefail
if [ $# -ne 6 ]; then
    sed -n '2,16p' "$0"
    exit 2
fi
scene=$1 mode=$2 frames=$3 rounds=$4 a=$5 b=$6
cd "$(dirname "$0")/.."
case $scene in
    */*|*.ron) path=$scene ;;
    *) path=scenes/$scene.ron ;;
esac
if [ "$(nproc)" -lt 2 ]; then
    echo "ab-frames: needs two cores, this machine has $(nproc)" >&2
    exit 1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
play() { # binary core dir
    mkdir -p "$3"
    taskset -c "$2" "$1" play "$path" --frames "$frames" --mode "$mode" --threads 1 \
        --width 640 --height 480 -o "$3" --stats "$3/stats.jsonl" > "$3/log" 2>&1
}
failed() { # binary dir
    echo "ab-frames: $1 failed:" >&2
    tail -3 "$2/log" >&2
    exit 1
}
median() { # stats.jsonl -> median render_ms
    python3 -c 'import json,statistics,sys;print("%.2f"%statistics.median(json.loads(l)["render_ms"] for l in open(sys.argv[1])))' "$1"
}
ratios=()
for r in $(seq "$rounds"); do
    ca=$(( (r + 1) % 2 )) cb=$(( r % 2 ))
    rm -rf "$tmp/a" "$tmp/b"
    play "$a" $ca "$tmp/a" & pa=$!
    play "$b" $cb "$tmp/b" & pb=$!
    fa=0 fb=0
    wait $pa || fa=1
    wait $pb || fb=1
    [ $fa = 0 ] || failed "$a" "$tmp/a"
    [ $fb = 0 ] || failed "$b" "$tmp/b"
    for f in "$tmp"/a/*.png; do
        cmp -s "$f" "$tmp/b/$(basename "$f")" || echo "DIFF $(basename "$f")"
    done
    ma=$(median "$tmp/a/stats.jsonl") mb=$(median "$tmp/b/stats.jsonl")
    ratio=$(python3 -c "print('%.3f' % ($mb / $ma))")
    ratios+=("$ratio")
    echo "round $r (A on core $ca): A $ma ms, B $mb ms, B / A $ratio"
done
python3 -c 'import statistics,sys;print("median B / A over %d rounds: %.3f" % (len(sys.argv)-1, statistics.median(map(float, sys.argv[1:]))))' "${ratios[@]}"
