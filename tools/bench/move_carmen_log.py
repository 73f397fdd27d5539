#!/usr/bin/env python3
"""Writes a copy of a CARMEN log (.clf or .clf.gz) moved by a rigid change of frame.

The odometry (ODOM) and the laser's robot and sensor poses (FLASER) are rotated by ANGLE
radians about the origin, then shifted by (TX, TY) metres; ranges and time stamps are kept.
The relations of the benchmark are relative poses, so the same relations score the moved
copy. Why: one real-log row's mean error moves by about +-0.003 m with the frame alone
(ACES: 0.0449-0.0478 m over six frames when 0.0423 as logged), so a change to the agents'
matching should be judged over several moved copies, not one draw (docs/REAL_LOGS.md).

  tools/bench/move_carmen_log.py aces.clf.gz /tmp/aces-r035.clf.gz --angle 0.35
  anchormap-import-carmen /tmp/aces-r035.clf.gz --output in.lcmlog   # then replay, eval
"""
import argparse
import gzip
import math
import sys


def open_text(path, mode):
    return gzip.open(path, mode + "t") if path.endswith(".gz") else open(path, mode)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("source")
    parser.add_argument("destination")
    parser.add_argument("--angle", type=float, default=0.0, help="rotation [rad]")
    parser.add_argument("--tx", type=float, default=0.0, help="shift along x [m]")
    parser.add_argument("--ty", type=float, default=0.0, help="shift along y [m]")
    args = parser.parse_args()
    c, s = math.cos(args.angle), math.sin(args.angle)

    def moved(fields, at):
        x, y, theta = (float(v) for v in fields[at:at + 3])
        heading = math.atan2(math.sin(theta + args.angle), math.cos(theta + args.angle))
        fields[at:at + 3] = ["%.6f" % v for v in
                             (c * x - s * y + args.tx, s * x + c * y + args.ty, heading)]

    lines = 0
    with open_text(args.source, "r") as source, open_text(args.destination, "w") as out:
        for line in source:
            fields = line.split()
            if fields and fields[0] == "ODOM" and len(fields) >= 4:
                moved(fields, 1)
                line = " ".join(fields) + "\n"
            elif fields and fields[0] == "FLASER" and len(fields) >= 2:
                after_ranges = 2 + int(fields[1])  # laser pose, then odometry pose
                if len(fields) < after_ranges + 6:
                    sys.exit(f"move_carmen_log: short FLASER line {lines + 1}")
                moved(fields, after_ranges)
                moved(fields, after_ranges + 3)
                line = " ".join(fields) + "\n"
            out.write(line)
            lines += 1
    print(f"move_carmen_log: {lines} lines, rotated {args.angle} rad, shifted "
          f"({args.tx}, {args.ty}) m -> {args.destination}")


if __name__ == "__main__":
    main()
