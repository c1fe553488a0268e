#!/usr/bin/env bash
# Idempotent set-up for building, running and testing modex-cube on Debian or
# Ubuntu with rustup: QEMU, OVMF, Bochs and an X toolbox for the tests from
# apt, the pinned nightly with its components and target from rustup. Safe to run again; it only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"
    elif command -v sudo >/dev/null; then sudo "$@"
    else die "need root for '$*' (run as root or install sudo)"; fi
}

# What the tests run, by the Debian package that brings it:
# - QEMU and OVMF: booting the images (every QEMU test, `cargo run`);
# - Bochs with its X display plugin and ROMs (tests/bochs.rs), and a virtual
#   X server with the tools that type into and read its windows (tests/bochs.rs,
#   sim/tests/window.rs).
missing=()
command -v qemu-system-x86_64 >/dev/null || missing+=(qemu-system-x86)
[ -f /usr/share/OVMF/OVMF_CODE.fd ] || missing+=(ovmf)
command -v bochs >/dev/null || missing+=(bochs)
[ -f /usr/share/bochs/BIOS-bochs-latest ] || missing+=(bochsbios)
[ -f /usr/share/vgabios/vgabios.bin ] && [ -f /usr/share/vgabios/vgabios-cirrus.bin ] || missing+=(vgabios)
dpkg-query -W -f='${Status}' bochs-x 2>/dev/null | grep -q 'ok installed' || missing+=(bochs-x)
command -v Xvfb >/dev/null || missing+=(xvfb)
command -v xdotool >/dev/null || missing+=(xdotool)
command -v xwd >/dev/null || missing+=(x11-apps)
if [ ${#missing[@]} -gt 0 ]; then
    command -v apt-get >/dev/null || die "please install ${missing[*]} with your package manager"
    say "installing ${missing[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi
say "$(qemu-system-x86_64 --version | head -n 1)"
say "bochs $(dpkg-query -W -f='${Version}' bochs 2>/dev/null || echo '(version unknown)')"

command -v rustup >/dev/null || die "rustup not found: install it from the Rust website, then run this again"
# rust-toolchain.toml names one dated nightly with its components and target;
# 'rustup toolchain install' with no name installs exactly that (and does
# nothing if it is already there).
toolchain=$(sed -n 's/^channel = "\(.*\)"/\1/p' rust-toolchain.toml)
[ -n "$toolchain" ] || die "rust-toolchain.toml names no channel"
if rustup run "$toolchain" rustc --version >/dev/null 2>&1; then
    say "toolchain $toolchain is installed"
else
    say "installing toolchain $toolchain (from rust-toolchain.toml)"
fi
rustup toolchain install >/dev/null 2>&1 || rustup toolchain install
say "$(rustup run "$toolchain" rustc --version)"
say "ready: 'cargo run --release' boots the kernel, 'cargo test' tests it"
