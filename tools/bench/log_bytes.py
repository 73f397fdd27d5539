#!/usr/bin/env python3
"""Bytes per channel of an LCM log (the server's outputs), for the scale figures.

usage: log_bytes.py LOG [DATA_SECONDS [UNTIL_UTIME]]
Prints one line per channel: messages, bytes, largest message, and bytes per data second
when DATA_SECONDS is given; then the totals. With UNTIL_UTIME, only the events stamped
before it (to compare two runs over the part both reached). (LCM log format: per event a 0xEDA1DA01 sync
word, event number, utime, channel and data lengths, channel, data.)
"""
import struct
import sys


def main():
    path = sys.argv[1]
    seconds = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
    until = int(sys.argv[3]) if len(sys.argv) > 3 else None
    per = {}
    with open(path, "rb") as f:
        while True:
            head = f.read(28)
            if len(head) < 28:
                break
            sync, _, utime, channel_len, data_len = struct.unpack(">IqqII", head)
            if sync != 0xEDA1DA01:
                sys.exit("log_bytes: lost sync")
            channel = f.read(channel_len).decode("ascii", "replace")
            f.seek(data_len, 1)
            if until is not None and utime >= until:
                continue
            count, total, largest = per.get(channel, (0, 0, 0))
            per[channel] = (count + 1, total + data_len, max(largest, data_len))
    print("| channel | messages | MB | largest kB | kB per data s |")
    print("|---|---|---|---|---|")
    rows = sorted(per.items())
    rows.append(("total", (sum(v[0] for v in per.values()), sum(v[1] for v in per.values()),
                           max([v[2] for v in per.values()] or [0]))))
    for channel, (count, total, largest) in rows:
        rate = "%.1f" % (total / 1e3 / seconds) if seconds > 0 else "-"
        print("| %s | %d | %.2f | %.1f | %s |" % (channel, count, total / 1e6, largest / 1e3, rate))


if __name__ == "__main__":
    main()
