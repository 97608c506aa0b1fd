#!/usr/bin/env bash
# Remakes the magstand-written logs in this directory (run from the repository root):
#   bash tests/data/magstand-written/make.sh
# They are checked in so that the import is tested against fixed files: a change to the log
# writers or to the simulator cannot silently move both ends of the round trip together.
set -euo pipefail
out=tests/data/magstand-written
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cargo run --release --quiet -- simulate --scenario builtin:czyba2015-stair --seed 2026 --logs \
  --set program.dwell_s=2 --set magnetometer.odr_hz=50 --out "$tmp"
cp "$tmp/recording.ulg" "$out/stair.ulg"
cp "$tmp/recording.bin" "$out/stair.bin"
# The simulator's ground truth: time and the motor disturbance (eq. 8's dmag).
python3 - "$tmp/recording.csv" "$out/stair-truth.csv" <<'PY'
import csv, sys
with open(sys.argv[1]) as f, open(sys.argv[2], "w", newline="") as g:
    r = csv.DictReader(f)
    cols = ["t_s", "true_dist_x_ut", "true_dist_y_ut", "true_dist_z_ut"]
    w = csv.writer(g, lineterminator="\n")
    w.writerow(cols)
    for row in r:
        w.writerow([row[c] for c in cols])
PY
