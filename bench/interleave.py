#!/usr/bin/env python3
"""Times commands in rounds, each round running every command once, in turn.

    interleave.py TASKS OUT_DIR RUNS [WARMUP]

TASKS: a file of `name|command` lines (the command split as a shell would,
run without one). Each command runs WARMUP (default 1) untimed rounds, then
RUNS timed ones; OUT_DIR gets one JSON file per task (the name with every
character but letters and digits as `_`):

    {"results": [{"command", "median", "mean", "min", "max", "user",
                  "system", "max_rss_kib", "times"}]}

(seconds; user and system are means over the timed runs; max_rss_kib the
peak resident memory of one more run under /usr/bin/time: wait4's figure
for a child spawned from this script starts at the script's own size,
about 10 MiB, which the kernel carries over through exec).

Why rounds and not each command's runs back to back (as hyperfine does): a
machine whose speed drifts, such as a virtual machine whose host takes its
cores for a few seconds at a time, then slows every command alike instead
of most runs of one of them, so that the ratio of two commands' medians
measures the commands rather than the moment each was run.
"""
import json
import os
import re
import shlex
import statistics
import subprocess
import sys
import tempfile
import time


def run_once(argv):
    """Wall seconds, user and system CPU seconds of one run."""
    devnull = os.open(os.devnull, os.O_RDWR)
    try:
        start = time.perf_counter()
        pid = os.posix_spawnp(argv[0], argv, os.environ,
                              file_actions=[(os.POSIX_SPAWN_DUP2, devnull, 1), (os.POSIX_SPAWN_DUP2, devnull, 2)])
        _, status, usage = os.wait4(pid, 0)
        wall = time.perf_counter() - start
    finally:
        os.close(devnull)
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        raise RuntimeError(f"`{shlex.join(argv)}` exited with {code}")
    return wall, usage.ru_utime, usage.ru_stime


def peak_rss_kib(argv):
    """Peak resident memory (KiB) of one run, measured by GNU time."""
    with tempfile.NamedTemporaryFile(mode="r", suffix=".rss") as out:
        done = subprocess.run(["/usr/bin/time", "-f", "%M", "-o", out.name] + argv,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if done.returncode != 0:
            raise RuntimeError(f"`{shlex.join(argv)}` exited with {done.returncode} under /usr/bin/time")
        return int(out.read().split()[-1])


def main():
    if len(sys.argv) not in (4, 5):
        sys.exit(__doc__)
    tasks_path, out_dir, runs = sys.argv[1], sys.argv[2], int(sys.argv[3])
    warmup = int(sys.argv[4]) if len(sys.argv) == 5 else 1
    tasks = []
    with open(tasks_path) as f:
        for number, line in enumerate(f, 1):
            if not line.strip():
                continue
            name, sep, command = line.rstrip("\n").partition("|")
            if not sep or not command.strip():
                sys.exit(f"{tasks_path}:{number}: expected `name|command`, got {line.strip()!r}")
            tasks.append((name, shlex.split(command)))
    if not tasks:
        sys.exit(f"{tasks_path}: no tasks")
    if not os.access("/usr/bin/time", os.X_OK):
        sys.exit("interleave.py: /usr/bin/time is missing (apt-get install time)")
    # A command that fails is dropped from later rounds (its JSON says so).
    failed = {}
    samples = {name: [] for name, _ in tasks}
    for round_number in range(warmup + runs):
        timed = round_number >= warmup
        print(f"\r{'round' if timed else 'warm-up'} {round_number + 1 - (warmup if timed else 0)}"
              f"/{runs if timed else warmup}   ", end="", file=sys.stderr, flush=True)
        for name, argv in tasks:
            if name in failed:
                continue
            try:
                sample = run_once(argv)
            except (RuntimeError, OSError) as e:
                failed[name] = str(e)
                continue
            if timed:
                samples[name].append(sample)
    print(file=sys.stderr)
    rss = {}
    for name, argv in tasks:
        if name not in failed:
            try:
                rss[name] = peak_rss_kib(argv)
            except RuntimeError as e:
                failed[name] = str(e)
    os.makedirs(out_dir, exist_ok=True)
    for name, argv in tasks:
        path = os.path.join(out_dir, re.sub(r"[^A-Za-z0-9]", "_", name) + ".json")
        if name in failed:
            result = {"command": shlex.join(argv), "failed": failed[name]}
        else:
            times = [s[0] for s in samples[name]]
            result = {
                "command": shlex.join(argv),
                "median": statistics.median(times),
                "mean": statistics.fmean(times),
                "min": min(times),
                "max": max(times),
                "user": statistics.fmean(s[1] for s in samples[name]),
                "system": statistics.fmean(s[2] for s in samples[name]),
                "max_rss_kib": rss[name],
                "times": times,
            }
        with open(path, "w") as f:
            json.dump({"results": [result]}, f, indent=1)


if __name__ == "__main__":
    main()
