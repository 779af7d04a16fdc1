#!/usr/bin/env bash
# Regenerates every figure and table shown in README.md into docs/.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cargo build --release -p stepdamp
bin=target/release/stepdamp
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Figs. 4–7 analogue: the README's main command.
$bin --quiet sweep --motor patent-motor --mode both --compensation both --from 1 --to 40 --points 60 --out "$tmp/patent" > docs/sweep-patent-motor.txt
cp "$tmp/patent/sweep.png" docs/sweep-patent-motor.png
cp "$tmp/patent/sweep.csv" docs/sweep-patent-motor.csv
# Issue 5: the patent's law and the estimated rotor angle side by side, open loop.
$bin --quiet sweep --motor patent-motor --mode open-loop --compensation off,patent,estimated --out "$tmp/nominal" > docs/sweep-estimated-nominal.txt
cp "$tmp/nominal/sweep.png" docs/sweep-estimated-nominal.png
$bin --quiet sweep --motor patent-motor --mode open-loop --compensation off,patent,estimated --load-torque 0.171 --out "$tmp/load" > docs/sweep-estimated-load.txt
cp "$tmp/load/sweep.png" docs/sweep-estimated-load.png
$bin --quiet sweep --motor docs/profiles/patent-motor-low-damping.toml --mode open-loop --compensation off,patent,estimated --out "$tmp/lowdamp" > docs/sweep-estimated-low-damping.txt
cp "$tmp/lowdamp/sweep.png" docs/sweep-estimated-low-damping.png
# Issue 4: identification from the planned servo runs (simulated, with current noise), then an
# open-loop sweep whose controller uses the identified profile instead of the true one.
$bin --quiet identify run --motor patent-motor --out "$tmp/idrun" > /dev/null
logs=()
for f in "$tmp"/idrun/run-*.csv; do logs+=(--log "$f"); done
# base.toml: the profile the runs were recorded with (the plan's [servo] settings).
$bin --quiet identify "${logs[@]}" --motor "$tmp/idrun/base.toml" \
    --out docs/profiles/patent-motor-identified.toml --report "$tmp/idrep" | grep -v ' s, fitted in ' > docs/identify-patent-motor.txt
cp "$tmp/idrep/spectrum.png" docs/identify-spectrum-patent-motor.png
cp "$tmp/idrep/residual.png" docs/identify-residual-patent-motor.png
# Refinement with the feed-forward on (the patent's criterion): before/after table.
$bin --quiet identify run --motor patent-motor --out "$tmp/refine" --refine | grep -v -e ' in [0-9.]* s$' -e '^wrote ' > docs/identify-refine-patent-motor.txt
cp "$tmp/refine/refine-summary.csv" docs/identify-refine-patent-motor.csv
$bin --quiet sweep --motor patent-motor --controller-motor docs/profiles/patent-motor-identified.toml --mode open-loop --compensation off,patent --out "$tmp/idsweep" > docs/sweep-identified.txt
# Summaries name the temporary directory; keep them free of it.
sed -i "s|$tmp/[a-z]*/|out/|" docs/*.txt
echo "figures written to docs/"
