"""Compile time of each translation unit of a build, from ninja's log.

Usage::

    python3 benchmarks/build_times.py [BUILD_DIR | BUILD_DIR/.ninja_log] [--limit 45] [--all]

BUILD_DIR defaults to the newest folder build/*/ of this checkout holding a ``.ninja_log`` (the
pip build's CMake build directory is build/<wheel tag>/, pyproject.toml's ``build-dir``).

Prints, from the latest entry of each output in ``.ninja_log`` (a rebuilt output's newer entry
replaces its older one):
  - each translation unit's compile time (outputs ending in .o / .obj), longest first, in seconds,
    flagging every one over --limit seconds (default 45);
  - the other steps (archive, link) with --all, else only their sum;
  - the total CPU seconds: the sum of every step's duration (ninja logs each command's wall time;
    a compiler is one thread, so this is its CPU time on a machine that was not oversubscribed);
  - the wall span of the build: first start to last end of the latest ninja run, and the total
    CPU seconds over it (the parallelism achieved). Entries of an earlier run (outputs that the
    latest, incremental run did not rebuild) are counted in the sums and their runs named.

Exit status 0, or 2 when no log is found. The runs are told apart by ninja's log v6/v7 third
column (an absolute timestamp taken when the command started: time minus start offset is the
same for a whole run), or, in older logs, by the end times starting over.
"""
from __future__ import annotations

import argparse
import glob
import os
import sys
import time
from dataclasses import dataclass

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@dataclass
class Entry:
    start_ms: int
    end_ms: int
    mtime: int
    output: str
    line: int  # position in the log
    run: int = 0  # which ninja invocation (0 = the oldest)

    @property
    def seconds(self) -> float:
        return (self.end_ms - self.start_ms) / 1e3


def find_log(path: str | None) -> str | None:
    if path:
        log = path if os.path.isfile(path) else os.path.join(path, ".ninja_log")
        return log if os.path.isfile(log) else None
    logs = glob.glob(os.path.join(ROOT, "build", "*", ".ninja_log"))
    return max(logs, key=os.path.getmtime) if logs else None


def read_log(log: str) -> tuple[str, list[Entry]]:
    """(header, every entry in file order)."""
    header, entries = "", []
    with open(log) as fh:
        for i, line in enumerate(fh):
            if line.startswith("#"):
                header = header or line.strip()
                continue
            fields = line.rstrip("\n").split("\t")
            if len(fields) < 4:
                continue
            try:
                entries.append(Entry(int(fields[0]), int(fields[1]), int(fields[2]), fields[3], i))
            except ValueError:
                continue
    return header, entries


def assign_runs(entries: list[Entry]) -> None:
    """Numbers each entry's ninja run (Entry.run, oldest 0)."""
    if entries and all(e.mtime > 10 ** 17 for e in entries):  # ns timestamps of the command starts
        origins = sorted({(e.mtime / 1e9 - e.start_ms / 1e3) for e in entries})
        runs, last = [], None  # origins within 2 s of each other are one run
        for o in origins:
            if last is None or o - last > 2.0:
                runs.append(o)
            last = o
        for e in entries:
            origin = e.mtime / 1e9 - e.start_ms / 1e3
            e.run = max(i for i, r in enumerate(runs) if r <= origin + 1e-6)
        return
    run, prev_end = 0, -1  # older logs: a run's entries are appended as they end
    for e in entries:
        if e.end_ms < prev_end:
            run += 1
        e.run, prev_end = run, e.end_ms


def short(output: str) -> str:
    """CMakeFiles/<target>.dir/cpp/x.cpp.o -> <target>: cpp/x.cpp"""
    parts = output.split("/")
    if len(parts) > 2 and parts[0] == "CMakeFiles" and parts[1].endswith(".dir"):
        name = "/".join(parts[2:])
        for ext in (".o", ".obj"):
            name = name[: -len(ext)] if name.endswith(ext) else name
        return f"{parts[1][:-4]}: {name}"
    return output


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("build_dir", nargs="?", help="a build directory or its .ninja_log (default: the newest "
                                                 "build/*/ holding one)")
    ap.add_argument("--limit", type=float, default=45.0, help="flag translation units over this many seconds")
    ap.add_argument("--all", action="store_true", help="also list the steps that are not compiles")
    args = ap.parse_args(argv)
    log = find_log(args.build_dir)
    if log is None:
        where = args.build_dir or os.path.join(ROOT, "build", "*")
        print(f"no .ninja_log in {where}", file=sys.stderr)
        return 2
    header, entries = read_log(log)
    assign_runs(entries)
    latest: dict[str, Entry] = {}
    for e in entries:  # a later entry of the same output replaces the earlier one
        latest[e.output] = e
    steps = sorted(latest.values(), key=lambda e: (-e.seconds, e.output))
    units = [e for e in steps if e.output.endswith((".o", ".obj"))]
    others = [e for e in steps if not e.output.endswith((".o", ".obj"))]
    last_run = max((e.run for e in entries), default=0)
    print(f"{log} ({header or 'no header'}; {len(entries)} entries, {len(latest)} outputs, "
          f"log written {time.strftime('%Y-%m-%d %H:%M', time.localtime(os.path.getmtime(log)))})")
    width = max([len(short(e.output)) for e in steps] + [20])
    print(f"\n{'translation unit':<{width}}{'seconds':>9}")
    print("-" * (width + 9))
    for e in units:
        flag = f"  OVER {args.limit:g} s" if e.seconds > args.limit else ""
        older = "" if e.run == last_run else f"  (an earlier run, #{e.run + 1} of {last_run + 1})"
        print(f"{short(e.output):<{width}}{e.seconds:>9.1f}{flag}{older}")
    if args.all:
        for e in others:
            print(f"{short(e.output):<{width}}{e.seconds:>9.1f}  (not a compile)")
    compile_s = sum(e.seconds for e in units)
    other_s = sum(e.seconds for e in others)
    total = compile_s + other_s
    print(f"\n{len(units)} translation units: {compile_s:.1f} s; {len(others)} other steps (archive, link, "
          f"...): {other_s:.1f} s; total CPU {total:.1f} s")
    run = [e for e in latest.values() if e.run == last_run]
    span = (max(e.end_ms for e in run) - min(e.start_ms for e in run)) / 1e3 if run else 0.0
    run_cpu = sum(e.seconds for e in run)
    print(f"wall span of the build (latest ninja run, {len(run)} of {len(latest)} outputs): {span:.1f} s "
          f"({span / 60:.1f} min), {run_cpu:.1f} CPU s over it = {run_cpu / span if span else 0:.2f} parallel")
    if len(run) < len(latest):
        print(f"  (the other {len(latest) - len(run)} outputs were last built by earlier runs)")
    over = [e for e in units if e.seconds > args.limit]
    if over:
        print(f"over {args.limit:g} s: " + ", ".join(f"{short(e.output)} ({e.seconds:.0f} s)" for e in over))
    else:
        print(f"no translation unit over {args.limit:g} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
