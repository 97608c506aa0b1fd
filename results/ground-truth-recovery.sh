#!/usr/bin/env bash
# Ground-truth recovery on the physics scenarios: identify on a stair going up, validate on a
# stair going down and on random steps, 20 Monte Carlo runs each (fresh seeds per run).
# Usage: bash results/ground-truth-recovery.sh OUTDIR   (about 2 minutes on 2 cores)
set -euo pipefail
out=${1:-ground-truth-recovery}
magstand() { cargo run --release --quiet -- "$@"; }
random='study.validation=["program={kind=\"random_steps\",off_s=10.0,count=40,min=0.0,max=1.0,dwell_min_s=1.0,dwell_max_s=4.0}","differential={amplitude=0.02,frequency_hz=0.7}"]'
for s in czyba2015-stair battery-sag bench-supply-stair; do
    magstand montecarlo --scenario "scenarios/$s.toml" --runs 20 --out "$out/$s-down" \
        --set 'study.validation=["program.direction=\"down\""]'
    magstand montecarlo --scenario "scenarios/$s.toml" --runs 20 --out "$out/$s-random" \
        --set "$random"
done
