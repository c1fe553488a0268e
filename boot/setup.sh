#!/usr/bin/env bash
# Idempotent set-up for building, running and testing modex-cube on Debian or
# Ubuntu with rustup: QEMU and OVMF (and, for the simulator's window tests,
# Xvfb, xdotool and xwd) from apt, the nightly's components and target from
# rustup. Safe to run again; it only installs what is missing.
set -euo pipefail

say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"
    elif command -v sudo >/dev/null; then sudo "$@"
    else die "need root for '$*' (run as root or install sudo)"; fi
}

missing=()
command -v qemu-system-x86_64 >/dev/null || missing+=(qemu-system-x86)
[ -f /usr/share/OVMF/OVMF_CODE.fd ] || missing+=(ovmf)
if [ ${#missing[@]} -gt 0 ]; then
    command -v apt-get >/dev/null || die "please install ${missing[*]} with your package manager"
    say "installing ${missing[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi
say "$(qemu-system-x86_64 --version | head -n 1)"

# The simulator's window tests (sim/tests/window.rs) run it under a virtual X
# server, type with xdotool and capture with xwd.
missing=()
command -v Xvfb >/dev/null || missing+=(xvfb)
command -v xdotool >/dev/null || missing+=(xdotool)
command -v xwd >/dev/null || missing+=(x11-apps)
if [ ${#missing[@]} -gt 0 ]; then
    command -v apt-get >/dev/null || die "please install ${missing[*]} with your package manager"
    say "installing ${missing[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi

command -v rustup >/dev/null || die "rustup not found: install it from the Rust website, then run this again"
if ! rustup run nightly rustc --version >/dev/null 2>&1; then
    say "installing a nightly toolchain"
    rustup toolchain install nightly --profile minimal
fi
rustup component add --toolchain nightly rust-src llvm-tools-preview rustfmt clippy >/dev/null
rustup target add --toolchain nightly x86_64-unknown-none >/dev/null

version=$(rustup run nightly rustc --version)
say "$version"
# bootloader =0.11.15 is pinned because 0.11.16+ need nightlies from 2026-07-10 on;
# it is tested with nightly 2026-05-19. Older nightlies lack features it uses.
date=$(sed -n 's/.*(\([0-9a-f]*\) \([0-9-]*\)).*/\2/p' <<<"$version")
if [ -n "$date" ] && [[ "$date" < "2025-01-01" ]]; then
    die "nightly from $date is too old for bootloader 0.11.15; run 'rustup update nightly'"
fi
say "ready: 'cargo run --release' boots the kernel, 'cargo test' tests it"
