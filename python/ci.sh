#!/usr/bin/env bash
# Python package CI: build the abi3 wheel (release, LTO), install it into a fresh virtual
# environment with the pinned test requirements, and run the pytest suite against the CLI.
#
#   bash python/ci.sh
#
# Environment:
#   CARGO_TARGET_DIR  build cache of the wheel (default: <repo>/target/python; keep it
#                     between runs: a cold release/LTO build takes minutes)
#   STEPDAMP_BIN      the stepdamp CLI the tests compare with (default: built here,
#                     `cargo build --release -p stepdamp`, as .ci/run's main command does)
#   PYTHON            the interpreter for the venv (default: python3, ≥ 3.9)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$root/target/python}"
py="${PYTHON:-python3}"
work="$root/target/python-ci"
rm -rf "$work"
mkdir -p "$work"
t0=$SECONDS

# maturin in its own throwaway venv (the build tool, not the test environment).
"$py" -m venv "$work/build-venv"
"$work/build-venv/bin/pip" install -q "maturin==1.7.4"
(cd "$here" && "$work/build-venv/bin/maturin" build --release --locked -o "$work/wheels")
wheel=$(ls "$work"/wheels/stepdamp-*.whl)
echo "built $wheel ($(du -k "$wheel" | cut -f1) KB) in $((SECONDS - t0)) s"

if [[ -z "${STEPDAMP_BIN:-}" ]]; then
    (cd "$root" && cargo build --release -p stepdamp)
    STEPDAMP_BIN="$root/target/release/stepdamp"
fi
export STEPDAMP_BIN

# A fresh environment: the pinned requirements, then the wheel.
"$py" -m venv "$work/venv"
"$work/venv/bin/pip" install -q -r "$here/requirements-ci.txt"
"$work/venv/bin/pip" install -q "$wheel"
# Run from outside the source tree so that the installed package is the one tested.
cd "$work"
"$work/venv/bin/python" -m pytest -q -p no:cacheprovider "$here/tests"
echo "python CI: $((SECONDS - t0)) s"
