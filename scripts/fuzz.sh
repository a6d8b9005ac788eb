#!/usr/bin/env bash
# Fuzzes every parser and the Context API with cargo-fuzz (libFuzzer).
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]
#
# Runs each target for SECONDS (default 60), FUZZ_JOBS targets at a time
# (default 2). Installs what it needs: the nightly toolchain and cargo-fuzz.
# The seed corpora are made from the repository's scenes and fixtures and
# from the BART files in OPENRT_BART_DIR (default ../shared/bart); neither
# the corpora nor the BART data are committed. Findings land in
# fuzz/artifacts/TARGET/, logs in fuzz/logs/TARGET.log, and a summary line
# per target (executions, coverage, corpus size, findings) at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
secs=${1:-60}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then targets=(aff ron obj texture api gltf); fi
jobs=${FUZZ_JOBS:-2}
bart=${OPENRT_BART_DIR:-$root/../shared/bart}

rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz --locked

# Seed corpora.
data=crates/openrt-scene/tests/data
mkdir -p fuzz/corpus/{aff,ron,obj,texture,api} fuzz/logs
cp "$data/sample.aff" "$data/sample_inc.aff" fuzz/corpus/aff/
# The main file and its include in one input (the aff target splits at 0xFF).
{ cat "$data/sample.aff"; printf '\377'; cat "$data/sample_inc.aff"; } >fuzz/corpus/aff/sample_with_inc
# The BART wrappers and the 10M-triangle terrain take seconds per input:
# the aff target fuzzes the BART files themselves.
for f in scenes/*.ron; do grep -q -E "bart:|Terrain" "$f" || cp "$f" fuzz/corpus/ron/; done
cp "$data/sample.obj" scenes/models/*.obj fuzz/corpus/obj/
cp "$data/sample.ppm" scenes/textures/* fuzz/corpus/texture/
if [ -d "$bart" ]; then
  find "$bart" -name '*.aff' -size -64k -exec cp {} fuzz/corpus/aff/ \;
  find "$bart" -name '*.ppm' -size -64k -exec cp {} fuzz/corpus/texture/ \;
else
  echo "fuzz.sh: no BART folder at $bart; seeding from the repository only" >&2
fi

cd fuzz
# Built once, before any target runs: `cargo fuzz run` then reuses the
# binaries (edit the sources during a run only in another checkout).
cargo +nightly fuzz build
run() {
  local t=$1
  # NOTE: -detect_leaks=0: the scene targets create contexts whose rayon
  # pools and background builds end their threads after the input is done;
  # LeakSanitizer then reports their thread-local storage and deques as
  # leaked (64 bytes and 1.5 kB, the only "findings" with leak checks on;
  # AddressSanitizer's own check at exit reports the pools' threads too).
  ASAN_OPTIONS="detect_leaks=0" cargo +nightly fuzz run "$t" "corpus/$t" -- -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
    -max_len=65536 -detect_leaks=0 -print_final_stats=1 >"logs/$t.log" 2>&1 ||
    echo "fuzz.sh: $t stopped with a finding (see fuzz/logs/$t.log)" >&2
}
export -f run
export secs
printf '%s\n' "${targets[@]}" | xargs -P "$jobs" -I{} bash -c 'run {}'

echo "target | seconds | executions | exec/s | coverage (edges) | features | corpus | findings"
for t in "${targets[@]}"; do
  log=logs/$t.log
  runs=$(grep -o 'Done [0-9]* runs' "$log" | awk '{print $2}' | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | awk '{print $2}')
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | awk '{print $2}')
  eps=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | awk '{print $2}' | tail -1)
  corpus=$(find "corpus/$t" -type f | wc -l)
  found=$(find "artifacts/$t" -type f 2>/dev/null | wc -l)
  echo "$t | $secs | ${runs:-?} | ${eps:-?} | ${cov:-?} | ${ft:-?} | $corpus | $found"
done
