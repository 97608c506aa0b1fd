#!/usr/bin/env bash
# The paper's figures from the paper-like scenario: identification stair up (seed 3),
# validation stair down (seed 4), the paper's model (3 RBFs at 0, 0.5, 1, width 4, local
# estimation). Usage: bash results/paper-figures.sh [OUTDIR]   (about 10 s)
set -euo pipefail
out=${1:-results/paper-figures}
work=$(mktemp -d)
magstand() { cargo run --release --quiet -- "$@"; }
magstand simulate --scenario scenarios/czyba2015-stair.toml --seed 3 --out "$work/ident"
magstand simulate --scenario scenarios/czyba2015-stair.toml --seed 4 \
    --set 'program.direction="down"' --out "$work/valid"
magstand fit --recording "$work/ident/recording.csv" --model-out "$work/paper-model.json" \
    --rbf 3 --centers 0,0.5,1 --width 4 --estimation local
magstand report --recording "$work/ident/recording.csv" --out "$work/report-ident"
magstand report --recording "$work/valid/recording.csv" --model "$work/paper-model.json" \
    --out "$work/report-valid"
mkdir -p "$out"
cp "$work/report-ident/deviation-vs-throttle.svg" "$out/fig2-deviation-identification.svg"
cp "$work/report-valid/deviation-vs-throttle.svg" "$out/fig3-deviation-validation.svg"
cp "$work/report-valid/rbf-weights.svg" "$out/fig6-rbf-weights.svg"
for a in x y z; do cp "$work/report-valid/model-$a.svg" "$out/fig7-model-$a.svg"; done
cp "$work/report-valid/e20-vs-throttle.svg" "$out/fig8-e20.svg"
cp "$work/report-valid/heading-vs-throttle.svg" "$out/heading-vs-throttle.svg"
cp "$work/paper-model.json" "$out/paper-model.json"
rm -rf "$work"
