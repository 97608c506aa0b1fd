#!/usr/bin/env bash
# One screenshot per section of the demo's report, rendered by headless Chromium.
# Usage: bash results/report-screenshots.sh   (runs the demo in a temporary folder first)
set -euo pipefail
root=$(pwd)
work=$(mktemp -d)
(cd "$work" && cargo run --release --quiet --manifest-path "$root/Cargo.toml" -- demo >/dev/null)
page="$work/magstand-demo/report/index.html"
mkdir -p results/report-screenshots
for i in 1 2 3; do
    # Show only section i (and the header), so each screenshot is one section.
    sed "s|</style>|section:not(#section-$i){display:none}</style>|" "$page" > "$work/only-$i.html"
    # Figures link to their SVG files next to the page: keep them resolvable.
    cp "$work/only-$i.html" "$work/magstand-demo/report/only-$i.html"
    chromium --headless --no-sandbox --disable-gpu --hide-scrollbars \
        --window-size=1150,2400 --screenshot="results/report-screenshots/section-$i.png" \
        "file://$work/magstand-demo/report/only-$i.html" 2>/dev/null
done
rm -rf "$work"
