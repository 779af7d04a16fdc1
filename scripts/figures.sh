#!/usr/bin/env bash
# Regenerates every figure and table shown in README.md into docs/.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cargo build --release -p stepdamp
bin=target/release/stepdamp
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Figs. 4–7 analogue: the README's main command.
$bin --quiet sweep --motor patent-motor --mode both --compensation both --from 1 --to 40 --points 60 --out "$tmp/patent"
cp "$tmp/patent/sweep.png" docs/sweep-patent-motor.png
cp "$tmp/patent/sweep.csv" docs/sweep-patent-motor.csv
echo "figures written to docs/"
