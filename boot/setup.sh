#!/usr/bin/env bash
# Idempotent set-up for building, running and testing modex-cube on Debian or
# Ubuntu with rustup: QEMU, OVMF, Bochs, an X toolbox and headless Chromium for the tests from
# apt, the pinned nightly with its components and targets from rustup. Safe to run again; it only installs what is missing.
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
# 32-bit OVMF: the 32-bit UEFI loader's boot (tests/uefi32.rs, --uefi32).
[ -f /usr/share/OVMF/OVMF32_CODE_4M.secboot.fd ] && [ -f /usr/share/OVMF/OVMF32_VARS_4M.fd ] || missing+=(ovmf-ia32)
command -v bochs >/dev/null || missing+=(bochs)
[ -f /usr/share/bochs/BIOS-bochs-latest ] || missing+=(bochsbios)
[ -f /usr/share/vgabios/vgabios.bin ] && [ -f /usr/share/vgabios/vgabios-cirrus.bin ] || missing+=(vgabios)
dpkg-query -W -f='${Status}' bochs-x 2>/dev/null | grep -q 'ok installed' || missing+=(bochs-x)
command -v Xvfb >/dev/null || missing+=(xvfb)
command -v xdotool >/dev/null || missing+=(xdotool)
command -v xwd >/dev/null || missing+=(x11-apps)
# Secure Boot (boot/secure_boot.rs): sbsign signs the UEFI loader with
# Authenticode, openssl makes the user's key, python3-venv holds virt-firmware.
command -v sbsign >/dev/null || missing+=(sbsigntool)
# efitools: the stick's .esl and .auth for firmware setups' key management.
command -v sign-efi-sig-list >/dev/null || missing+=(efitools)
command -v openssl >/dev/null || missing+=(openssl)
[ -f /usr/share/OVMF/OVMF_CODE_4M.secboot.fd ] && [ -f /usr/share/OVMF/OVMF_VARS_4M.ms.fd ] || missing+=(ovmf)
python3 -c 'import venv, ensurepip' 2>/dev/null || missing+=(python3-venv)
# NASM assembles the worst-case BIOS's option ROM (tests/hostile_bios.rs).
command -v nasm >/dev/null || missing+=(nasm)
# Headless Chromium runs the web page in its tests and benchmark
# (tests/web_page.rs, benches/web_page.rs, the browser/ crate); the full
# chromium package serves as well if it is there.
command -v chromium-headless-shell >/dev/null || command -v chromium >/dev/null \
    || missing+=(chromium-headless-shell)
if [ ${#missing[@]} -gt 0 ]; then
    command -v apt-get >/dev/null || die "please install ${missing[*]} with your package manager"
    say "installing ${missing[*]}"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
fi
say "$(qemu-system-x86_64 --version | head -n 1)"

# Shim and MokManager, signed by Microsoft and Debian, from Debian's packages
# (not installed: downloaded and unpacked into a cache outside the repository).
# apt-get download checks each .deb against the SHA-256 in the signed index;
# the files unpacked are then checked against the .deb's own md5sums. The
# runner reads them from $MODEX_CUBE_SHIM_DIR, or
# ${XDG_CACHE_HOME:-~/.cache}/modex-cube/shim.
shim_dir=${MODEX_CUBE_SHIM_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/modex-cube/shim}
fetch_shim() {
    local work
    work=$(mktemp -d)
    trap 'rm -rf "$work"' RETURN
    # The package lists may be absent when nothing else needed installing.
    apt-cache show shim-signed shim-helpers-amd64-signed >/dev/null 2>&1 || as_root apt-get update -qq
    ( cd "$work" && chmod 755 . && apt-get download -q shim-signed shim-helpers-amd64-signed >/dev/null ) \
        || die "apt-get download shim-signed shim-helpers-amd64-signed failed (run 'apt-get update' first?)"
    local deb package
    mkdir -p "$work/root"
    for deb in "$work"/*.deb; do
        package=$(dpkg-deb -f "$deb" Package)
        # The SHA-256 apt's signed index gives for this version, checked again
        # here so that a cache filled by hand cannot slip through.
        local want got
        want=$(apt-cache show "$package=$(dpkg-deb -f "$deb" Version)" | sed -n 's/^SHA256: //p' | head -n 1)
        got=$(sha256sum "$deb" | cut -d' ' -f1)
        [ -n "$want" ] && [ "$want" = "$got" ] || die "$deb: SHA-256 $got is not the index's ($want)"
        dpkg-deb -x "$deb" "$work/root"
        dpkg-deb -e "$deb" "$work/control-$package"
        ( cd "$work/root" && md5sum --quiet -c "$work/control-$package/md5sums" ) \
            || die "$deb: the unpacked files do not match its md5sums"
        cp "$work/root/usr/share/doc/$package/copyright" "$work/copyright-$package"
        echo "$package $(dpkg-deb -f "$deb" Version) $got" >>"$work/packages"
    done
    mkdir -p "$shim_dir"
    install -m 644 "$work/root/usr/lib/shim/shimx64.efi.signed" "$shim_dir/shimx64.efi"
    install -m 644 "$work/root/usr/lib/shim/mmx64.efi.signed" "$shim_dir/mmx64.efi"
    install -m 644 "$work"/copyright-* "$shim_dir/"
    install -m 644 "$work/packages" "$shim_dir/packages"
}
if [ -f "$shim_dir/shimx64.efi" ] && [ -f "$shim_dir/mmx64.efi" ] && [ -f "$shim_dir/packages" ]; then
    say "shim and MokManager are in $shim_dir"
else
    say "fetching shim and MokManager from Debian's shim-signed and shim-helpers-amd64-signed"
    fetch_shim
fi
while read -r package version sha; do say "$package $version (sha256 $sha)"; done <"$shim_dir/packages"

# virt-fw-vars (PyPI's virt-firmware) writes certificates into OVMF's variable
# store (tests/secure_boot.rs); in a venv under target/, as pip wants.
venv=target/tools/virt-firmware
if [ -x "$venv/bin/virt-fw-vars" ]; then
    say "virt-fw-vars is in $venv"
else
    say "installing virt-firmware into $venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q virt-firmware
fi
say "$(command -v chromium-headless-shell || command -v chromium): $(chromium-headless-shell --version 2>/dev/null || chromium --version)"
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
# A toolchain installed before rust-toolchain.toml named a target lacks it
# ('toolchain install' does not add it then): add each one missing, such as
# wasm32-unknown-unknown for the web page.
installed_targets=$(rustup target list --installed --toolchain "$toolchain")
for target in $(sed -n 's/^targets = \[\(.*\)\]/\1/p' rust-toolchain.toml | tr -d '",'); do
    grep -qx "$target" <<<"$installed_targets" || rustup target add --toolchain "$toolchain" "$target"
done
say "$(rustup run "$toolchain" rustc --version)"
say "ready: 'cargo run --release' boots the kernel, 'cargo test' tests it"
