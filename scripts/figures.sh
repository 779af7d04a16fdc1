#!/usr/bin/env bash
# Regenerates every figure and table the docs publish from the sweeps and identification.
#
#   bash scripts/figures.sh [OUT_DIR [PROFILE_DIR]]
#
# OUT_DIR (default docs/generated) receives the PNG plots and the text and CSV tables they
# plot; PROFILE_DIR (default docs/profiles) receives the identified profile. CI's
# figure check (scripts/check-figures.sh) runs this into a temporary directory and compares
# the text and CSV with the committed ones. STEPDAMP_BIN, if set, is the binary to use
# instead of building target/release/stepdamp.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
out="$(realpath -m "${1:-docs/generated}")"
profiles="$(realpath -m "${2:-docs/profiles}")"
mkdir -p "$out" "$profiles"
if [[ -n "${STEPDAMP_BIN:-}" ]]; then
    bin="$STEPDAMP_BIN"
else
    cargo build --release -p stepdamp
    bin=target/release/stepdamp
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Figs. 4–7 analogue: the README's main command.
$bin --quiet sweep --motor patent-motor --mode both --compensation both --from 1 --to 40 --points 60 --out "$tmp/patent" > "$out/sweep-patent-motor.txt"
cp "$tmp/patent/sweep.png" "$out/sweep-patent-motor.png"
cp "$tmp/patent/sweep.csv" "$out/sweep-patent-motor.csv"
# The patent's law and the estimated rotor angle side by side, open loop
# (docs/design.md#beyond-the-patent-the-estimated-angle).
$bin --quiet sweep --motor patent-motor --mode open-loop --compensation off,patent,estimated --out "$tmp/nominal" > "$out/sweep-estimated-nominal.txt"
cp "$tmp/nominal/sweep.png" "$out/sweep-estimated-nominal.png"
$bin --quiet sweep --motor patent-motor --mode open-loop --compensation off,patent,estimated --load-torque 0.171 --out "$tmp/load" > "$out/sweep-estimated-load.txt"
cp "$tmp/load/sweep.png" "$out/sweep-estimated-load.png"
$bin --quiet sweep --motor docs/profiles/patent-motor-low-damping.toml --mode open-loop --compensation off,patent,estimated --out "$tmp/lowdamp" > "$out/sweep-estimated-low-damping.txt"
cp "$tmp/lowdamp/sweep.png" "$out/sweep-estimated-low-damping.png"
# Identification from the planned servo runs (simulated, with current noise), then an
# open-loop sweep whose controller uses the identified profile instead of the true one.
$bin --quiet identify run --motor patent-motor --out "$tmp/idrun" > /dev/null
logs=()
for f in "$tmp"/idrun/run-*.csv; do logs+=(--log "$f"); done
# base.toml: the profile the runs were recorded with (the plan's [servo] settings).
$bin --quiet identify "${logs[@]}" --motor "$tmp/idrun/base.toml" \
    --out "$profiles/patent-motor-identified.toml" --report "$tmp/idrep" | grep -v ' s, fitted in ' > "$out/identify-patent-motor.txt"
cp "$tmp/idrep/spectrum.png" "$out/identify-spectrum-patent-motor.png"
cp "$tmp/idrep/residual.png" "$out/identify-residual-patent-motor.png"
# Refinement with the feed-forward on (the patent's criterion): before/after table.
$bin --quiet identify run --motor patent-motor --out "$tmp/refine" --refine | grep -v -e ' in [0-9.]* s$' -e '^wrote ' > "$out/identify-refine-patent-motor.txt"
cp "$tmp/refine/refine-summary.csv" "$out/identify-refine-patent-motor.csv"
$bin --quiet sweep --motor patent-motor --controller-motor "$profiles/patent-motor-identified.toml" --mode open-loop --compensation off,patent --out "$tmp/idsweep" > "$out/sweep-identified.txt"
# Summaries name the temporary directory and the profile directory; keep them free of both,
# so that a regeneration anywhere reads the same as the committed one.
sed -i -e "s|$tmp/[a-z]*/|out/|" -e "s|$profiles/|docs/profiles/|" "$out"/*.txt
echo "figures written to $out (identified profile in $profiles)"
