#!/usr/bin/env python3
"""The real-log table of issue 11: Intel, ACES and FR079, 1/2/3 robots, sequential and
--simultaneous, each through exactly the user's three commands with their defaults:

  anchormap-import-carmen LOG.clf.gz --output IN [--split N] [--simultaneous]
  anchormap-replay --log IN --output OUT
  anchormap-eval --map OUT --relations LOG.relations --odometry IN --json --relation-errors REL

Per run: mean / median translational and mean rotational relation error, evaluated and
skipped relations (across_frames must be 0), the relations whose two ends lie in different
robots' pieces ("joining", scored separately from the per-relation file), the replay's CPU
time (user + sys, getrusage of the child) and x real time (the replayed data span over the
CPU time), and the server's loop closure and scan encounter counts from its final status line.

Runs one replay at a time under `nice` (the machine is shared). Example:
  tools/bench/real_log_table.py --bin build/bin --data ../shared/data/benchmark --work /tmp/t
  tools/bench/real_log_table.py --logs aces --configs 1,2,2s   # a subset
  tools/bench/real_log_table.py --replay-option=--reduced-graph=true   # not the defaults
Writes WORK/table.md (markdown) and WORK/table.json; prints the table as it goes.
"""

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import time

# Kümmerle et al. 2009 (Graph Mapping) and Hess et al. 2016 (Cartographer): mean
# translational relation error, m.
PUBLISHED = {"intel": (0.031, 0.0229), "aces": (0.044, 0.0375), "fr079": (0.056, 0.0452)}


def run(cmd, log_path):
    """Runs cmd with stdout+stderr to log_path; returns (exit code, CPU s, wall s)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    with open(log_path, "w") as log:
        code = subprocess.call(cmd, stdout=log, stderr=subprocess.STDOUT)
    wall = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return code, cpu, wall


def robot_spans(import_text):
    """Each robot's piece in the log's own clock (the relations' clock): (start, end)."""
    spans = []
    lines = import_text.splitlines()
    for i, line in enumerate(lines):
        m = re.match(r"\s*robot\s+(\S+)\s.*?([-\d.]+) \.\. ([-\d.]+) s;", line)
        if not m:
            continue
        start, end = float(m.group(2)), float(m.group(3))
        if i + 1 < len(lines):
            shift = re.search(r"shifted by ([-\d.]+) s", lines[i + 1])
            if shift:  # --simultaneous: the piece was moved by `shift`; undo it
                start -= float(shift.group(1))
                end -= float(shift.group(1))
        spans.append((start, end))
    return spans


def replayed_span(import_text):
    """The data time the replay covers (the robots' pieces as replayed, shifted or not)."""
    starts, ends = [], []
    for m in re.finditer(r"\s*robot\s+\S+\s.*?([-\d.]+) \.\. ([-\d.]+) s;", import_text):
        starts.append(float(m.group(1)))
        ends.append(float(m.group(2)))
    return max(ends) - min(starts) if starts else float("nan")


def joining(rel_path, spans):
    """Relations whose ends lie in different robots' pieces: count, mean/median t, mean rot."""
    if len(spans) < 2:
        return None

    def piece(t):
        for k, (a, b) in enumerate(spans):
            if a - 1e-6 <= t <= b + 1e-6:
                return k
        return -1

    rows = []
    with open(rel_path) as f:
        for line in f:
            parts = line.split()
            if len(parts) < 5 or line.startswith("#"):
                continue
            t1, t2, _, et, er = map(float, parts[:5])
            if piece(t1) != piece(t2):
                rows.append((et, er))
    if not rows:
        return {"count": 0}
    return {
        "count": len(rows),
        "mean_m": statistics.mean(r[0] for r in rows),
        "median_m": statistics.median(r[0] for r in rows),
        "mean_rad": statistics.mean(r[1] for r in rows),
    }


def source_counts(replay_text, name):
    """The final status line's counts of one encounter source ("loop" or "scan")."""
    lines = [l for l in replay_text.splitlines() if "server: robots" in l]
    if not lines:
        return None
    m = re.search(name + r": candidates (\d+) accepted (\d+) no_match (\d+) weak (\d+) gate (\d+) "
                  r"kept (\d+) unconfirmed (\d+)", lines[-1])
    if not m:
        return None
    keys = ["candidates", "accepted", "no_match", "weak", "gate", "kept", "unconfirmed"]
    counts = dict(zip(keys, map(int, m.groups())))
    counts["rejected"] = counts["no_match"] + counts["weak"] + counts["gate"] + counts["unconfirmed"]
    return counts


def one(args, log, config):
    robots = int(config[0])
    simultaneous = config.endswith("s")
    name = f"{log}-{config}"
    base = os.path.join(args.work, name)
    data_log = os.path.join(args.data, log + ".clf.gz")
    relations = os.path.join(args.data, log + ".relations")
    imp = [os.path.join(args.bin, "anchormap-import-carmen"), data_log, "--output", base + ".in"]
    if robots > 1:
        imp += ["--split", str(robots)]
    if simultaneous:
        imp.append("--simultaneous")
    code, _, _ = run(imp, base + ".import.txt")
    if code != 0:
        return {"name": name, "error": "import failed"}
    replay = ["nice", "-n", str(args.nice), os.path.join(args.bin, "anchormap-replay"), "--log",
              base + ".in", "--output", base + ".out"] + args.replay_option
    code, cpu, wall = run(replay, base + ".replay.txt")
    if code != 0:
        return {"name": name, "error": "replay failed"}
    ev = [os.path.join(args.bin, "anchormap-eval"), "--map", base + ".out", "--relations",
          relations, "--odometry", base + ".in", "--json", "--relation-errors", base + ".rel"]
    code, _, _ = run(ev, base + ".eval.json")
    if code != 0:
        return {"name": name, "error": "eval failed"}
    with open(base + ".eval.json") as f:
        evaluation = json.load(f)
    with open(base + ".import.txt") as f:
        import_text = f.read()
    with open(base + ".replay.txt") as f:
        replay_text = f.read()
    span = replayed_span(import_text)
    result = {
        "name": name,
        "log": log,
        "robots": robots,
        "simultaneous": simultaneous,
        "mean_m": evaluation["translation_m"]["mean"],
        "median_m": evaluation["translation_m"]["median"],
        "mean_rad": evaluation["rotation_rad"]["mean"],
        "evaluated": evaluation["evaluated"],
        "skipped": evaluation["skipped"],
        "joining": joining(base + ".rel", robot_spans(import_text)),
        "cpu_s": cpu,
        "wall_s": wall,
        "data_s": span,
        "x_real_time": span / cpu if cpu > 0 else float("nan"),
        "loop": source_counts(replay_text, "loop"),
        "scan": source_counts(replay_text, "scan"),
    }
    if not args.keep_logs:
        for suffix in (".in", ".out"):
            os.remove(base + suffix)
    return result


def row(r):
    if "error" in r:
        return f"| {r['name']} | {r['error']} |" + " |" * 9
    gm, carto = PUBLISHED[r["log"]]
    j = r["joining"]
    if j is None:
        joins = "-"
    elif j["count"] == 0:
        joins = "0"
    else:
        joins = f"{j['count']}, {j['mean_m']:.4f} (median {j['median_m']:.4f})"
    across = r["skipped"]["across_frames"]
    if j is not None and across > 0:  # never joined: eval could not score these
        joins += f"; {across} across frames, not scored"
    loop, scan = r["loop"] or {}, r["scan"] or {}
    lc = f"{loop.get('accepted', '?')} / {loop.get('rejected', '?')}"
    se = f"{scan.get('accepted', '?')} / {scan.get('rejected', '?')}" if r["robots"] > 1 else "-"
    return (f"| {r['name']} | {r['mean_m']:.4f} | {r['median_m']:.4f} | {r['mean_rad']:.4f} | "
            f"{r['evaluated']} / {r['skipped']['across_frames']} | {joins} | "
            f"{r['cpu_s']:.1f} | {r['x_real_time']:.1f}x | {lc} | {se} | {gm} / {carto} |")


HEADER = ("| run | mean t [m] | median t [m] | mean rot [rad] | evaluated / across_frames | "
          "joining relations: n, mean t [m] | replay CPU [s] | x real time | loop closures "
          "accepted / rejected | scan encounters accepted / rejected | Graph Mapping / "
          "Cartographer [m] |\n|" + "---|" * 11)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(os.path.dirname(here))
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bin", default=os.path.join(root, "build", "bin"))
    parser.add_argument("--data", default=os.path.join(root, "..", "shared", "data", "benchmark"))
    parser.add_argument("--work", default="/tmp/anchormap-real-log-table")
    parser.add_argument("--logs", default="intel,aces,fr079")
    parser.add_argument("--configs", default="1,2,2s,3,3s",
                        help="robots, with s for --simultaneous")
    parser.add_argument("--nice", type=int, default=5)
    parser.add_argument("--replay-option", action="append", default=[], metavar="OPTION",
                        help="an option for anchormap-replay beyond the defaults, e.g. "
                        "--replay-option=--reduced-graph=true (repeatable)")
    parser.add_argument("--keep-logs", action="store_true",
                        help="keep the imported and replayed LCM logs (large)")
    args = parser.parse_args()
    os.makedirs(args.work, exist_ok=True)
    results = []
    print(HEADER, flush=True)
    for log in args.logs.split(","):
        for config in args.configs.split(","):
            r = one(args, log, config)
            results.append(r)
            print(row(r), flush=True)
            with open(os.path.join(args.work, "table.json"), "w") as f:
                json.dump(results, f, indent=1)
    with open(os.path.join(args.work, "table.md"), "w") as f:
        f.write(HEADER + "\n" + "\n".join(row(r) for r in results) + "\n")
    return 0 if all("error" not in r for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
