#!/usr/bin/env bash
# Ablation of the estimated-angle compensation (docs/beyond-the-patent.md, "What the angle estimate buys"):
# the same three open-loop sweeps as scripts/figures.sh, once with the normal build and
# once built with `--cfg stepdamp_ablate_load_angle` (a research build of the core, not a
# Cargo feature, so no crate can switch it on in a production build), which keeps the
# current-loop inverse, the R̂ trim and the K̂m correction but evaluates the compensation
# at δ̂ = 0 (θ_cmd). Writes docs/generated/ablation.txt. The ablated build goes to its own target
# directory (its RUSTFLAGS differ, so it must not share the normal build's artefacts).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cargo build --release -p stepdamp
RUSTFLAGS="${RUSTFLAGS:-} --cfg stepdamp_ablate_load_angle" CARGO_TARGET_DIR=target/ablate-load-angle \
    cargo build --release -p stepdamp
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
{
    for build in "full:target/release/stepdamp" "load angle forced to 0:target/ablate-load-angle/release/stepdamp"; do
        for case in "nominal|--motor patent-motor" "load 0.171 N·m|--motor patent-motor --load-torque 0.171" \
            "low damping|--motor docs/profiles/patent-motor-low-damping.toml"; do
            printf '\n## %s build, %s\n' "${build%%:*}" "${case%%|*}"
            # shellcheck disable=SC2086
            "${build#*:}" --quiet sweep ${case#*|} --mode open-loop --compensation off,patent,estimated --out "$tmp/s" |
                grep -v -e '^wrote ' -e ' simulated in '
        done
    done
} > docs/generated/ablation.txt
echo "wrote docs/generated/ablation.txt"
