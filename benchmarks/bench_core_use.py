"""How many cores a command asks for, over its run: its process tree's runnable threads,
sampled from ``/proc`` (Linux), beside its wall and CPU time.

    python benchmarks/bench_core_use.py [--every 0.05] [--cores 2] -- COMMAND [ARGS ...]

On a machine shared with other work, a command's CPU time over its wall time says more about
the load than about the command. What it *asks for* does not depend on the load: every
``--every`` seconds this counts the threads of the command's processes (it and all its
descendants) that are running or waiting for a core (state ``R`` in
``/proc/<pid>/task/<tid>/stat``). The share of samples with ``0``, ``1``, ``≥ 2`` of them, and
the mean of ``min(runnable, cores)`` (the cores it would keep busy on an idle machine), tell a
command that runs one thing at a time from one that fills the cores. On a loaded machine the
samples stretch with the load but keep their proportions as long as the command's threads are
slowed alike. The counts are of threads, so a process idling in a spin-wait counts as asking.

Printed: wall seconds, CPU seconds (user + sys of the command and its reaped descendants),
CPU / wall, the load average before and after, and the demand profile.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path


def _children(pid: int, parents: dict[int, int]) -> set[int]:
    tree = {pid}
    grew = True
    while grew:
        grew = False
        for p, parent in parents.items():
            if parent in tree and p not in tree:
                tree.add(p)
                grew = True
    return tree


def _stat_fields(path: Path) -> list[str] | None:
    try:
        text = path.read_text()
    except OSError:  # (gone between the listing and the read)
        return None
    # the command name is in parentheses and may hold spaces: split after its last ")"
    return text[text.rindex(")") + 2 :].split()


def _runnable(root: int) -> int:
    """The runnable threads of ``root``'s process tree now."""
    parents = {}
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            fields = _stat_fields(Path(entry.path) / "stat")
            if fields is not None:
                parents[int(entry.name)] = int(fields[1])
    count = 0
    for pid in _children(root, parents):
        try:
            tasks = os.scandir(f"/proc/{pid}/task")
        except OSError:
            continue
        for task in tasks:
            fields = _stat_fields(Path(task.path) / "stat")
            if fields is not None and fields[0] == "R":
                count += 1
    return count


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--every", type=float, default=0.05, help="seconds between samples")
    parser.add_argument("--cores", type=int, default=os.cpu_count() or 1)
    parser.add_argument("command", nargs=argparse.REMAINDER)
    args = parser.parse_args()
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        parser.error("give the command to run after --")
    load_before = os.getloadavg()
    started = time.perf_counter()
    proc = subprocess.Popen(command)
    samples: Counter[int] = Counter()
    while proc.poll() is None:
        samples[_runnable(proc.pid)] += 1
        time.sleep(args.every)
    wall = time.perf_counter() - started
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = usage.ru_utime + usage.ru_stime
    n = sum(samples.values()) or 1
    # the sampler's own thread is not in the tree; a sample of the tree that is all waiting
    # (I/O, a lock, the pool's queue) counts 0
    busy = sum(min(k, args.cores) * c for k, c in samples.items()) / n
    shares = {
        "0": samples[0] / n,
        "1": samples[1] / n,
        "≥2": sum(c for k, c in samples.items() if k >= 2) / n,
    }
    print(
        f"wall {wall:.1f} s, CPU {cpu:.1f} s (user {usage.ru_utime:.1f} + sys "
        f"{usage.ru_stime:.1f}), CPU/wall {cpu / wall:.2f}; load "
        f"{load_before[0]:.2f} → {os.getloadavg()[0]:.2f}; exit {proc.returncode}",
        file=sys.stderr,
    )
    print(
        f"runnable threads ({n} samples): "
        + ", ".join(f"{k} {v:.0%}" for k, v in shares.items())
        + f"; mean cores asked for (≤ {args.cores}) {busy:.2f}",
        file=sys.stderr,
    )
    sys.exit(proc.returncode)


if __name__ == "__main__":
    main()
