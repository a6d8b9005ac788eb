#!/usr/bin/env bash
# Distributed rendering figures: plays SCENES for FRAMES frames under
# mpirun with 2, 3 and 4 ranks (1 rank = one process, no MPI) and prints a
# Markdown table of per-frame medians: bytes sent, broadcast, slowest
# worker commit, render and gather, and the whole frame.
#
#   scripts/mpi-figures.sh [FRAMES] [SCENE...]      (needs `cargo build --release -p openrt --features mpi`)
#
# Threads per rank: 2 for one process, else 1, so that ranks x threads <= 2
# on this 2-core machine where possible; runs with more ranks than cores
# are marked oversubscribed. Rank 0 only coordinates (it renders no tiles).
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-30}
shift || true
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then scenes=(kitchen museum16k robots); fi
bin=target/release/openrt
cores=$(nproc)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
out=$(mktemp -d)
echo "Made by \`scripts/mpi-figures.sh $frames ${scenes[*]}\` on $cores cores ($(date -u +%Y-%m-%d)); $frames frames from frame 100, 640x480 GL-like; medians per frame."
echo
echo "| scene | ranks x threads | tiles | bytes sent | broadcast ms | worker commit ms | render + gather ms | frame ms | fps | tiles stolen | note |"
echo "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|"
for s in "${scenes[@]}"; do
  for run in 1:dynamic 2:dynamic 3:dynamic 3:static 4:dynamic; do
    ranks=${run%%:*}
    order=${run##*:}
    threads=$([ "$ranks" -eq 1 ] && echo 2 || echo 1)
    dir=$out/$s-$ranks-$order
    cmd=("$bin" --mpi-tiles "$order" play "scenes/$s.ron" --frames "100..$((100 + frames))" --mode gl --threads "$threads" --stats "$dir.jsonl")
    if [ "$ranks" -eq 1 ]; then "${cmd[@]}" >/dev/null 2>&1; else mpirun -n "$ranks" --oversubscribe "${cmd[@]}" >/dev/null 2>&1; fi
    python3 - "$dir.jsonl" "$s" "$ranks" "$threads" "$cores" "$order" <<'PY'
import json, statistics, sys
path, scene, ranks, threads, cores, order = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), sys.argv[6]
rows = [json.loads(l) for l in open(path)][1:]  # the first frame sends the whole scene
med = lambda xs: statistics.median(xs) if xs else float("nan")
d = [r.get("distributed") for r in rows]
# A frame: rank 0's commit, the broadcast, then render and gather.
frame = med([r["commit_ms"] + r["render_ms"] + (r["distributed"]["broadcast_ms"] if r.get("distributed") else 0) for r in rows])
busy = ranks * threads if ranks == 1 else (ranks - 1) * threads + 1
note = "oversubscribed" if busy > cores else ""
if ranks == 1:
    print(f"| {scene} | 1 x {threads} (one process) | - | - | - | - | {med([r['render_ms'] for r in rows]):.1f} | {frame:.1f} | {1000/frame:.1f} | - | {note} |")
else:
    print(f"| {scene} | {ranks} x {threads} | {order} | {med([x['bytes_sent'] for x in d]):.0f} | {med([x['broadcast_ms'] for x in d]):.2f} | {med([x['worker_commit_ms'] for x in d]):.2f} | {med([x['render_gather_ms'] for x in d]):.1f} | {frame:.1f} | {1000/frame:.1f} | {med([x['tiles_stolen'] for x in d]):.0f} | {note} |")
PY
  done
done
rm -rf "$out"
