#!/usr/bin/env bash
# Makes `qemu-system-arm` available for the firmware golden test without installing the
# Debian package: `apt-get install qemu-system-arm` would pull qemu-system-common of the
# distribution's QEMU version and so remove a newer, already installed `qemu-utils`.
#
# Instead: download the .deb into .ci/cache/, unpack it with `dpkg -x` into
# .ci/cache/qemu/, and install only the shared libraries that `ldd` reports missing
# (refusing any apt transaction that would remove a package).
#
# Idempotent: does nothing when qemu-system-arm is on PATH or already unpacked and runs.
# Prints the path of the binary on its last line.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cache="$root/.ci/cache"
dest="$cache/qemu"
bin="$dest/usr/bin/qemu-system-arm"

export DEBIAN_FRONTEND=noninteractive

works() { "$1" --version >/dev/null 2>&1; }

if command -v qemu-system-arm >/dev/null 2>&1 && works qemu-system-arm; then
    echo "install-qemu: using $(command -v qemu-system-arm) ($(qemu-system-arm --version | head -n1))"
    command -v qemu-system-arm
    exit 0
fi
if [[ -x "$bin" ]] && works "$bin"; then
    echo "install-qemu: already unpacked ($("$bin" --version | head -n1))"
    echo "$bin"
    exit 0
fi

sudo_() { if [[ "$(id -u)" -eq 0 ]]; then "$@"; else sudo "$@"; fi; }

mkdir -p "$cache"
deb="$(ls "$cache"/qemu-system-arm_*.deb 2>/dev/null | head -n1 || true)"
if [[ -z "$deb" ]]; then
    # `apt-get update` only if the package index does not know the package yet.
    if ! apt-cache show qemu-system-arm >/dev/null 2>&1 \
        || ! (cd "$cache" && apt-get download qemu-system-arm); then
        sudo_ apt-get update
        (cd "$cache" && apt-get download qemu-system-arm)
    fi
    deb="$(ls "$cache"/qemu-system-arm_*.deb | head -n1)"
fi
echo "install-qemu: unpacking $(basename "$deb")"
rm -rf "$dest"
dpkg -x "$deb" "$dest"
[[ -x "$bin" ]] || { echo "install-qemu: $bin missing in $deb" >&2; exit 1; }

# Shared libraries the binary cannot find, e.g. "libfdt.so.1".
missing_libs() { ldd "$bin" | awk '/not found/ { print $1 }' | sort -u; }

libs="$(missing_libs)"
if [[ -n "$libs" ]]; then
    # Library packages the .deb depends on, e.g. "libfdt1".
    deps="$(dpkg-deb -f "$deb" Depends | tr ',' '\n' | sed -E 's/[|(].*//; s/^ +//; s/ +$//' \
        | grep '^lib' | sort -u)"
    pkgs=()
    for so in $libs; do
        # Debian's naming: libfoo.so.N -> libfooN, libfoo2.so.N -> libfoo2-N.
        stem="${so%%.so.*}"
        ver="${so##*.so.}"
        ver="${ver%%.*}"
        if [[ "$stem" =~ [0-9]$ ]]; then cand="$stem-$ver"; else cand="$stem$ver"; fi
        if grep -qx "$cand" <<<"$deps"; then
            pkgs+=("$cand")
        else
            echo "install-qemu: no dependency named $cand for $so; installing all missing library dependencies" >&2
            while read -r d; do
                dpkg-query -W -f='${Status}' "$d" 2>/dev/null | grep -q 'install ok installed' \
                    || pkgs+=("$d")
            done <<<"$deps"
        fi
    done
    mapfile -t pkgs < <(printf '%s\n' "${pkgs[@]}" | sort -u)
    echo "install-qemu: missing $(echo $libs) -> installing ${pkgs[*]}"
    plan="$(apt-get install -s -y --no-install-recommends "${pkgs[@]}" 2>&1)" || {
        sudo_ apt-get update
        plan="$(apt-get install -s -y --no-install-recommends "${pkgs[@]}")"
    }
    if grep -q '^Remv ' <<<"$plan"; then
        echo "install-qemu: refusing, installing ${pkgs[*]} would remove packages:" >&2
        grep '^Remv ' <<<"$plan" >&2
        exit 1
    fi
    sudo_ apt-get install -y --no-install-recommends "${pkgs[@]}"
    libs="$(missing_libs)"
    if [[ -n "$libs" ]]; then
        echo "install-qemu: still missing: $libs" >&2
        exit 1
    fi
fi

works "$bin" || { "$bin" --version; exit 1; }
echo "install-qemu: ok ($("$bin" --version | head -n1))"
echo "$bin"
