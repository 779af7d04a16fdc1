#!/usr/bin/env bash
# Current-sensor noise (docs/beyond-the-patent.md, "Assumptions and robustness"): open-loop sweeps of
# patent-motor with the patent's law and the estimated angle, at σ = 5 mA and 20 mA of
# current-sensor noise, six seeds each. For each resonance it prints the peak-to-peak
# velocity error near it (largest within ±10 % of the theoretical speed), per seed and as
# the RMS over the seeds. Writes docs/generated/noise.txt.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
# BIN=path runs another build (e.g. an older commit's) instead of building this tree.
bin=${BIN:-target/release/stepdamp}
[[ -n ${BIN:-} ]] || cargo build --release -p stepdamp
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
speeds=$($bin resonance --motor patent-motor | sed -n 's/^resonance k=\([0-9]*\) *\([0-9.]*\) rad\/s.*/\1=\2/p' | tr '\n' ' ')
{
    echo "open loop, patent-motor; peak-to-peak velocity error near each resonance, rad/s"
    for sigma in 0.005 0.02; do
        for seed in 1 2 3 4 5 6; do
            $bin --quiet sweep --motor patent-motor --mode open-loop --compensation patent,estimated \
                --current-noise "$sigma" --seed "$seed" --out "$tmp/s$seed" > /dev/null
        done
        for seed in 1 2 3 4 5 6; do tail -n +2 "$tmp/s$seed/sweep.csv" | sed "s/^/$seed,/"; done |
            awk -F, -v sigma="$sigma" -v speeds="$speeds" '
                BEGIN { n = split(speeds, kv, " "); for (i = 1; i <= n; i++) { split(kv[i], p, "="); k[i] = p[1]; w[i] = p[2] } }
                { for (i = 1; i <= n; i++) if ($4 >= 0.9 * w[i] && $4 <= 1.1 * w[i]) {
                      key = $1 SUBSEP $3 SUBSEP i; if ($6 > peak[key]) peak[key] = $6 } }
                END {
                    printf "\nσ = %g A\n%-6s %-10s %s\n", sigma, "k", "law", "seed 1..6, then RMS over seeds"
                    for (i = 1; i <= n; i++) for (l = 1; l <= 2; l++) {
                        law = (l == 1) ? "patent" : "estimated"; s2 = 0; line = ""
                        for (s = 1; s <= 6; s++) { v = peak[s SUBSEP law SUBSEP i]; s2 += v * v; line = line sprintf(" %.3f", v) }
                        printf "k=%-4s %-10s%s   RMS %.3f\n", k[i], law, line, sqrt(s2 / 6)
                    }
                }'
    done
} | tee "${OUT:-docs/generated/noise.txt}"
