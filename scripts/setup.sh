#!/usr/bin/env bash
# One-time set-up of a fresh Debian machine: system packages and the pinned
# Rust toolchain. Safe to run again.
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
# Debian packages: a C toolchain for -sys crates; Xvfb, Mesa's software OpenGL
# and the X libraries winit opens, for the viewer and its smoke test; Open MPI
# and libclang (the `mpi` crate's bindings) for the `mpi` feature and its test.
pkgs=(build-essential pkg-config xvfb xauth libgl1-mesa-dri libglx-mesa0 libegl1 libegl-mesa0
  libxkbcommon-x11-0 libxcursor1 libxrandr2 libxi6 libx11-xcb1 fonts-dejavu-core
  openmpi-bin libopenmpi-dev libclang-dev)
missing=()
for p in "${pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi
if ! command -v rustup >/dev/null 2>&1; then
  echo "rustup is required (https://rustup.rs); install it, then run this script again" >&2
  exit 1
fi
# rust-toolchain.toml pins the channel and components; this installs them.
rustup show active-toolchain >/dev/null
cargo fetch --locked
