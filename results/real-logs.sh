#!/usr/bin/env bash
# Reproduces results/real-logs.md: imports the public logs of tests/data/real-logs, fits the
# internal compass of each flight with the Earth field fitted out (magstand fit --earth fit),
# and compares magstand's model with the autopilots' straight lines on held-out time blocks.
# Usage: bash results/real-logs.sh  (from the repository root; writes results/real-logs.md)
set -euo pipefail
M="cargo run --release -q --"
D=tests/data/real-logs
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
out=results/real-logs.md.tmp
compat=$T/compat.md
{
echo "# Real logs: magstand's model against the autopilots' straight lines"
echo
echo "Made by \`bash results/real-logs.sh\` on $(date -u +%Y-%m-%d) ($(nproc) cores)."
echo "Each log is imported (\`magstand import\`), the Earth field is fitted out of the flight with the"
echo "logged attitude (\`magstand fit --earth fit\`, stream delay estimated), and three models of the"
echo "internal compass are fitted on the same rows: magstand's automatic model, PX4's line and"
echo "ArduPilot's compassmot line. The numbers are RMS errors in uT on the time blocks the fits held"
echo "out (every third block), per axis x / y / z; lower is better."
echo
echo "| log | rows | input | Earth field fitted (N, E, D uT) | delay s | magstand | PX4 line | ArduPilot line |"
echo "|---|---|---|---|---|---|---|---|"
} > "$out"
fit() { # log csv input method -> "x / y / z" held-out RMSE, plus the Earth line
  $M fit --recording "$1" --model-out "$T/m.json" --earth fit --inputs "$2" --method "$3" > "$T/fit.txt" 2>&1 || { echo "fit failed: $(tail -1 "$T/fit.txt")" >&2; return 1; }
}
row() { # name file kind input [import args...]
  local name=$1 file=$2 kind=$3 input=$4; shift 4
  $M import --"$kind" "$D/$file" --out "$T/r.csv" "$@" > "$T/imp.txt" 2>&1 || { echo "| $name | import failed: $(tail -1 "$T/imp.txt" | sed 's#^error: ##' | cut -c1-200) |||||||" >> "$out"; return; }
  local rows; rows=$(($(wc -l < "$T/r.csv") - 1))
  local cells=()
  local earth="" delay=""
  for method in local-linear px4 ardupilot; do
    if fit "$T/r.csv" "$input" "$method"; then
      if [ "$method" = local-linear ]; then
        # The autopilots' own figures, printed by the same fit on the same rows.
        awk -v name="$name" -v input="$input" '
          /^ +magstand /   { m = sprintf("%.2f / %.2f / %.2f", $2, $3, $4); mi = $8 }
          /^ +PX4 line /   { p = sprintf("%.2f / %.2f / %.2f", $3, $4, $5) }
          /^ +compassmot / { a = sprintf("%.2f / %.2f / %.2f", $2, $3, $4); ai = $8 }
          END { printf "| %s | %s | %s | %s | %s | %s %% | %s %% |\n", name, input, m, p, a, mi, ai }
        ' "$T/fit.txt" >> "$compat"
      fi
      cells+=("$(awk '/^ +[xyz] /{printf "%s%.2f", (n++ ? " / " : ""), $4}' "$T/fit.txt")")
      earth=$(sed -n 's/.*: N \([-0-9.]*\) E \([-0-9.]*\) D \([-0-9.]*\) uT.*/\1, \2, \3/p' "$T/fit.txt")
      delay=$(sed -n 's/.*magnetometer \([0-9.]*\) s behind.*/\1/p' "$T/fit.txt")
    else
      cells+=("fit failed: $(tail -1 "$T/fit.txt" | sed "s#$T/##g; s#^error: ##" | cut -c1-110)")
    fi
  done
  echo "| $name | $rows | $input | $earth | $delay | ${cells[0]} | ${cells[1]} | ${cells[2]} |" >> "$out"
}
row "ArduPilot quad, MAG2 (internal), to 238 s" ardupilot-log171-quad.bin dataflash current --to-s 238
row "ArduPilot quad, MAG2 (internal), to 238 s" ardupilot-log171-quad.bin dataflash throttle --to-s 238
row "ArduPilot quad, MAG (external, control)" ardupilot-log171-quad.bin dataflash current --to-s 238 --mag 0
row "PX4 6C quad, sensor_mag[1] (internal)" px4-fmuv6c-quad-local.ulg ulog current
row "PX4 6C quad, sensor_mag[0] (external, control)" px4-fmuv6c-quad-local.ulg ulog current --mag 0
row "PX4 hexa (18 s at 1 Hz)" px4-fmuv5-hexa-sample-small.ulg ulog current
row "PX4 UAVCAN quad (calibrated vehicle_magnetometer)" px4-fmuv3-uavcan-esc-status.ulg ulog current
row "PX4 corrupt file" px4-corrupt-actuator-armed-wrong-size.ulg ulog current
{
echo
echo "The same fits in the autopilots' own terms, as \`magstand fit\` prints them: R² on all rows per"
echo "axis x / y / z (PX4 keeps its line's slope only) and ArduPilot compassmot's interference, the field"
echo "change at the top of the recorded range in % of its fixed 530 mG (magstand's model, then compassmot's"
echo "line; ArduPilot calls below 30 % fine and above 60 % unacceptable)."
echo
echo "| log | input | magstand R² | PX4 line R² | compassmot R² | interference, magstand | interference, compassmot |"
echo "|---|---|---|---|---|---|---|"
cat "$compat" 2>/dev/null || true
} >> "$out"
cat >> "$out" <<'NOTES'

What the table says:

- The ArduPilot log (10 Hz compass, 155 s of flight with turns up to 46 degrees of tilt and the
  whole compass rose) is the one with enough data. Its fitted Earth field, 56.6 uT at -65.7
  degrees inclination, matches the World Magnetic Model for Canberra (about 57 uT, -66 degrees),
  though nothing told the fit where the vehicle was. On held-out time blocks magstand's model is
  better than both lines on x and y (y: 1.23 against 1.88 and 1.78 uT with the throttle as input)
  and equal on z. The external compass, the control, has almost nothing for either to explain.
- The PX4 logs record the magnetometer at 1 to 3 Hz for 18 to 92 s. That is too little to fit
  an Earth field and a nonlinear disturbance on held-out data: the 6C's fitted Earth field is
  implausible (3 uT horizontal), its delay sits at the 0.5 s search limit, and the three models
  trade places axis by axis within the noise. The hexa has 18 samples (the flight fit needs 20)
  and the UAVCAN log never has the motors off with a magnetometer sample, so the eq. 9 reference
  is missing. These are limits of the logs, reported as errors, not fits.
- In the autopilots' terms: on the ArduPilot log's internal compass magstand's model explains
  more of the field change than PX4's line on y (R² 0.71 against 0.39 with the throttle as
  input) and as much on x and z; compassmot would report 22-30 % interference, inside
  ArduPilot's "fine" band, so its own check would not have flagged this compass. On the PX4 6C
  the negative R² values of the lines (and of the model on the external compass) say the same
  as the held-out errors: at 1 Hz for 92 s there is nothing reliable to fit, and `magstand fit`
  now warns that the delay is unresolvable at that row spacing and sits at its search limit.
- The corrupt file stops at its malformed message; what precedes it has no motor outputs, and
  the import says so.
NOTES
mv "$out" results/real-logs.md
echo "wrote results/real-logs.md"
