#!/usr/bin/env python3
"""The server's work per slice of data, from `anchormap-replay --log-level info
--status-period-s S` (its "status at T s of data: STATUS | WORK | process cpu s ..." lines):
every counter's difference between consecutive lines, one row per counter, one column per
slice. Counters are named by their section and label ("fold_work.reference_builds",
"grid_work.moved", "chunk_work.sent", "cpu.fold", "loop.candidates", "graph.folded", ...).

  tools/bench/work_slices.py REPLAY_LOG [SUBSTRING,...]

With substrings, only the counters whose name holds one of them. The counts are the same in
every run of the same input and options; the CPU seconds ("cpu.*", "process", "main_thread")
follow the minute (this VM's speed drifts by tens of percent).
"""
import re
import sys


def counters(text):
    """(name, value) pairs of one status line's text, in order."""
    out, section, previous = [], '', ''
    for token in text.split():
        bare = token.strip(',();')
        if re.fullmatch(r'-?\d+(\.\d+)?', bare):
            out.append((section + previous, float(bare)))
        elif token == '|':
            section, previous = '', ''
            continue
        elif bare.endswith(':'):
            head = bare[:-1]
            if head == 'work' and previous:
                head = previous + '_work'
            elif head == 's' and previous == 'cpu':
                head = 'cpu'
            section, previous = head + '.', ''
            continue
        else:
            previous = bare
        if token.endswith(';'):
            section = ''
    return out


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    wanted = sys.argv[2].split(',') if len(sys.argv) > 2 else None
    rows = []
    for line in open(sys.argv[1]):
        m = re.search(r'status at (\d+) s of data: (.*)', line)
        if m:
            text = m.group(2).replace('process cpu s', 'process').replace('main thread',
                                                                           'main_thread')
            rows.append((int(m.group(1)), counters(text)))
    if not rows:
        sys.exit('no "status at" lines (run with --log-level info --status-period-s S)')
    names = [name for name, _ in rows[0][1]]
    print(f"{'counter':36s}" + ''.join(f"{t:>10d}" for t, _ in rows))
    for i, name in enumerate(names):
        if wanted and not any(w in name for w in wanted):
            continue
        values = [r[1][i][1] for r in rows if i < len(r[1])]
        deltas = [values[0]] + [b - a for a, b in zip(values, values[1:])]
        digits = 2 if name.startswith('cpu.') or name in ('process', 'main_thread') else 0
        print(f"{name:36s}" + ''.join(f"{d:10.{digits}f}" for d in deltas))


if __name__ == '__main__':
    main()
