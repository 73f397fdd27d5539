#!/usr/bin/env python3
"""Compile CPU of the same files in two configured build trees, alternated file by file.

usage: scripts/compile_cpu_ab.py BUILD_A BUILD_B {tests|others} [STEP] [OFFSET]

Takes every STEP-th file (from OFFSET) of the sorted *_test.cc files (`tests`) or of the
other project files (`others`) that both trees' compile_commands.json list, compiles each
in A and in B (A first on even files, B first on odd ones: the machine's speed drifts),
without a compiler launcher (ccache), into a scratch object, and prints the user + system
CPU seconds of each and the totals. Generated sources must exist (configure both trees).
Used for docs/ARCHITECTURE.md, "CI's time" (precompiled headers).
"""
import json
import os
import resource
import shlex
import subprocess
import sys
import tempfile
import time


def project_files(build, kind, source_root):
    with open(os.path.join(build, 'compile_commands.json')) as f:
        commands = json.load(f)
    chosen = {}
    for c in commands:
        path = c['file']
        if not path.startswith(source_root + os.sep):
            continue  # generated stubs (precompiled-header hosts)
        if (kind == 'tests') == path.endswith('_test.cc'):
            chosen[path] = c
    return chosen


def compile_cpu(command, obj):
    args = shlex.split(command['command'])
    if os.path.basename(args[0]) == 'ccache':
        args = args[1:]
    args[args.index('-o') + 1] = obj
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(args, cwd=command['directory'], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main():
    if len(sys.argv) < 4 or sys.argv[3] not in ('tests', 'others'):
        sys.exit(__doc__)
    build_a, build_b, kind = sys.argv[1:4]
    step = int(sys.argv[4]) if len(sys.argv) > 4 else 1
    offset = int(sys.argv[5]) if len(sys.argv) > 5 else 0
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    a = project_files(build_a, kind, root)
    b = project_files(build_b, kind, root)
    files = sorted(set(a) & set(b))[offset::step]
    total_a = total_b = 0.0
    with tempfile.TemporaryDirectory() as scratch:
        obj = os.path.join(scratch, 'file.o')
        for i, path in enumerate(files):
            if i % 2 == 0:
                cpu_a = compile_cpu(a[path], obj)
                cpu_b = compile_cpu(b[path], obj)
            else:
                cpu_b = compile_cpu(b[path], obj)
                cpu_a = compile_cpu(a[path], obj)
            total_a += cpu_a
            total_b += cpu_b
            print('%s %.2f %.2f' % (os.path.relpath(path, root), cpu_a, cpu_b), flush=True)
    if files:
        print('total: %d files, A %.1f CPU s, B %.1f CPU s, B/A %.3f (%s UTC)' %
              (len(files), total_a, total_b, total_b / total_a, time.strftime('%H:%M', time.gmtime())))


if __name__ == '__main__':
    main()
