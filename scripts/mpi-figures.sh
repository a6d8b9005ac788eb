#!/usr/bin/env bash
# Distributed rendering figures: plays SCENES for FRAMES frames under
# mpirun with several ranks (1 rank = one process, no MPI) and prints a
# Markdown table of per-frame medians: bytes sent, broadcast, slowest
# worker commit, render and gather, and the whole frame.
#
#   scripts/mpi-figures.sh [FRAMES] [SCENE...]      (needs `cargo build --release -p openrt --features mpi`)
#
# RUNS (environment): the runs, each `ranks:threads:tiles`; by default
# `1:2:dynamic 2:1:dynamic 3:1:dynamic 3:1:static 4:1:dynamic`, so that
# ranks x threads <= 2 on the 2-core machine where possible; on the 16-core
# machine e.g. `1:16:dynamic 2:16:dynamic 3:8:dynamic 5:4:dynamic 9:2:dynamic`.
# MODES: `gl`, `whitted` or both (default `gl`). OPENRT: the binary
# (default target/release/openrt). MPIRUN_ARGS: more arguments for mpirun.
# Runs with more busy threads than cores are marked oversubscribed. Rank 0
# only coordinates (it renders no tiles).
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-30}
shift || true
scenes=("$@")
if [ ${#scenes[@]} -eq 0 ]; then scenes=(kitchen museum16k robots); fi
read -r -a runs <<<"${RUNS:-1:2:dynamic 2:1:dynamic 3:1:dynamic 3:1:static 4:1:dynamic}"
read -r -a modes <<<"${MODES:-gl}"
read -r -a extra <<<"${MPIRUN_ARGS:-}"
bin=${OPENRT:-target/release/openrt}
cores=$(nproc)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "Made by \`RUNS='${runs[*]}' MODES='${modes[*]}' scripts/mpi-figures.sh $frames ${scenes[*]}\` on $cores cores ($(date -u +%Y-%m-%d)); $frames frames from frame 100, 640x480; medians per frame."
echo
echo "| scene | mode | ranks x threads | tiles | bytes sent | broadcast ms | worker commit ms | render + gather ms | frame ms | fps | tiles stolen | note |"
echo "|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|"
for s in "${scenes[@]}"; do
  for mode in "${modes[@]}"; do
    for run in "${runs[@]}"; do
      IFS=: read -r ranks threads order <<<"$run"
      dir=$out/$s-$mode-$ranks-$threads-$order
      cmd=("$bin" --mpi-tiles "$order" play "scenes/$s.ron" --frames "100..$((100 + frames))" --mode "$mode" --threads "$threads" --stats "$dir.jsonl")
      if [ "$ranks" -gt 1 ]; then
        cmd=(mpirun -n "$ranks" --oversubscribe ${extra[@]+"${extra[@]}"} "${cmd[@]}")
      fi
      if ! "${cmd[@]}" >"$dir.log" 2>&1; then
        echo "$s $mode $run failed:" >&2
        tail -n 20 "$dir.log" >&2
        continue
      fi
      python3 - "$dir.jsonl" "$s" "$mode" "$ranks" "$threads" "$cores" "$order" <<'PY'
import json, statistics, sys
path, scene, mode, ranks, threads, cores, order = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6]), sys.argv[7]
mode = {"gl": "GL-like", "whitted": "Whitted"}.get(mode, mode)
rows = [json.loads(l) for l in open(path)][1:]  # the first frame sends the whole scene
med = lambda xs: statistics.median(xs) if xs else float("nan")
d = [r.get("distributed") for r in rows]
# A frame: rank 0's commit, the broadcast, then render and gather.
frame = med([r["commit_ms"] + r["render_ms"] + (r["distributed"]["broadcast_ms"] if r.get("distributed") else 0) for r in rows])
busy = ranks * threads if ranks == 1 else (ranks - 1) * threads + 1
note = "oversubscribed" if busy > cores else ""
if ranks == 1:
    print(f"| {scene} | {mode} | 1 x {threads} (one process) | - | - | - | - | {med([r['render_ms'] for r in rows]):.1f} | {frame:.1f} | {1000/frame:.1f} | - | {note} |")
else:
    print(f"| {scene} | {mode} | {ranks} x {threads} | {order} | {med([x['bytes_sent'] for x in d]):.0f} | {med([x['broadcast_ms'] for x in d]):.2f} | {med([x['worker_commit_ms'] for x in d]):.2f} | {med([x['render_gather_ms'] for x in d]):.1f} | {frame:.1f} | {1000/frame:.1f} | {med([x['tiles_stolen'] for x in d]):.0f} | {note} |")
PY
    done
  done
done
