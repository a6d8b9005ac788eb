#!/usr/bin/env bash
# Starts the viewer under Xvfb on the BART kitchen, plays a few frames and
# writes a screenshot of the real window (plus a JSON report of the overlay).
# Usage: scripts/viewer-smoke.sh [OUT.png] [FRAMES]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/viewer-smoke.png}
frames=${2:-5}
cargo build --release -q -p openrt-viewer
mkdir -p "$(dirname "$out")"
# eframe's glow backend runs on Mesa's software OpenGL under Xvfb.
LIBGL_ALWAYS_SOFTWARE=1 timeout 300 xvfb-run -a -s "-screen 0 1280x800x24" \
  target/release/openrt-viewer scenes/kitchen.ron --screenshot "$out" --frames "$frames"
echo "screenshot: $out, report: ${out%.png}.json"
cat "${out%.png}.json"; echo
