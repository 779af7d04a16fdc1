#!/usr/bin/env bash
# CI's figure check: regenerates what scripts/figures.sh and scripts/noise.sh publish into a
# temporary directory and fails if a text or CSV table, or the identified profile, differs from
# the committed one. (scripts/ablation.sh needs a second release build with another cfg, and
# scripts/study.sh a Python environment and minutes of CPU: their outputs are not checked here.)
#
#   bash scripts/check-figures.sh
#
# The simulator and the fit are deterministic, so the files must match exactly, except lines
# that report wall time (`… s wall …`), which are left out of the comparison. The PNG plots are
# not compared byte for byte (rasterisation may differ between machines); the CSV and TXT they
# plot are. STEPDAMP_BIN, if set, is passed on to figures.sh (else it builds the release binary).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
bash scripts/figures.sh "$tmp/generated" "$tmp/profiles" > "$tmp/figures.log"
BIN="${STEPDAMP_BIN:-target/release/stepdamp}" OUT="$tmp/generated/noise.txt" bash scripts/noise.sh > /dev/null

# Every table and summary figures.sh writes, and the profile it identifies.
pairs=()
for f in "$tmp"/generated/*.txt "$tmp"/generated/*.csv; do
    pairs+=("docs/generated/$(basename "$f")" "$f")
done
pairs+=(docs/profiles/patent-motor-identified.toml "$tmp/profiles/patent-motor-identified.toml")

strip() { grep -v ' s wall' "$1" || true; }
failed=0
for ((i = 0; i < ${#pairs[@]}; i += 2)); do
    committed=${pairs[i]} fresh=${pairs[i + 1]}
    if [[ ! -f "$committed" ]]; then
        echo "FAILED: $committed is written by scripts/figures.sh but not committed"
        failed=1
    elif ! diff -u --label "$committed (committed)" --label "$committed (regenerated)" \
        <(strip "$committed") <(strip "$fresh"); then
        failed=1
    else
        echo "same: $committed"
    fi
done
# The PNG files figures.sh writes must exist in the repository too (not compared).
for f in "$tmp"/generated/*.png; do
    [[ -f "docs/generated/$(basename "$f")" ]] || { echo "FAILED: docs/generated/$(basename "$f") missing"; failed=1; }
done
if [[ $failed -ne 0 ]]; then
    echo "docs figures differ from what the scripts write: run them and commit the result, with the reason" >&2
    exit 1
fi
echo "docs figures: the committed tables match scripts/figures.sh and scripts/noise.sh"
