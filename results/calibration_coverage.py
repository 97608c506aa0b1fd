#!/usr/bin/env python3
"""How often a calibrated dead zone's reported sd holds the independent generator's truth.

Usage: calibration_coverage.py DIR [DIR ...]

Each DIR holds recordings written by `WRITE_RECORDINGS=DIR independent-suite N` (the
generator's `NN-case-seedS.csv`) and, beside each, the diagnosis `magstand diagnose
--recording R.csv --json R.json` wrote for it without a scenario. The generator's dead zone
is the stand's (by its motor count: the default stand's 4 motors 0.12, the hexacopter's 6
0.06, the octocopter's 8 0.10; see tests/standgen), or 0.25 in the case `11-dead-zone-*`.
Prints, per DIR, the calibrated dead zones with an sd, how many lie within 2 and 3 sd of the
truth, the median sd and the median |error| / sd, and every one 3 sd or more off.
"""
import glob
import json
import os
import statistics
import sys

DEAD_ZONE_BY_MOTORS = {4: 0.12, 6: 0.06, 8: 0.10}


def truth(csv_path):
    if os.path.basename(csv_path).startswith("11-dead-zone"):
        return 0.25
    with open(csv_path) as f:
        motors = sum(1 for name in f.readline().strip().split(",") if name.startswith("thr_"))
    return DEAD_ZONE_BY_MOTORS[motors]


def main(dirs):
    for d in dirs:
        sds, zs, off = [], [], []
        without_sd = 0
        for js in sorted(glob.glob(os.path.join(d, "*.json"))):
            csv = js[: -len(".json")] + ".csv"
            calibration = json.load(open(js))["baseline"]["calibration"]
            dz = next((c for c in calibration if c["name"] == "motors.dead_zone"), None)
            if dz is None:
                continue
            if not dz.get("sd"):
                without_sd += 1
                continue
            z = (dz["value"] - truth(csv)) / dz["sd"]
            sds.append(dz["sd"])
            zs.append(abs(z))
            if abs(z) >= 3:
                off.append(f"  {os.path.basename(js)}: {dz['value']:.4f} +- {dz['sd']:.4f}, {z:+.1f} sd")
        if not zs:
            print(f"{d}: no calibrated dead zone with an sd ({without_sd} without)")
            continue
        print(
            f"{d}: {len(zs)} with an sd ({without_sd} without): within 2 sd {sum(z < 2 for z in zs)}, "
            f"within 3 sd {sum(z < 3 for z in zs)}; median sd {statistics.median(sds):.4f}, "
            f"median |error|/sd {statistics.median(zs):.2f}"
        )
        print("\n".join(off))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1:])
