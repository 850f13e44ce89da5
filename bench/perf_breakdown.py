#!/usr/bin/env python3
"""Sorts the samples of `perf script` output (taken with perf record -g) into costs and prints each cost's share.

Each sample goes to the first cost in COSTS whose keys occur in any frame of its call stack, so the order is the
priority: the system calls first (where the kernel's share of a request is spent), then the coordinator's own steps,
then allocation and the HTTP library, then the rest. With --ms-per-tile (the bench's coordinator CPU per tile) each
share is also given in ms per tile. Usage: perf script -i perf.data | bench/perf_breakdown.py [--ms-per-tile MS]
"""
import argparse
import collections
import sys

COSTS = [
    ("job result image (finish: encode and write the EXR)", ["JobService::finalize", "write_exr"]),
    ("store: file writes (log commits, checkpoint copies)", ["pwrite64", "__libc_pwrite"]),
    ("store: fdatasync (group commit, checkpoints)", ["fdatasync"]),
    ("store: file reads (checkpoint copies)", ["pread64", "__libc_pread"]),
    ("store: file locks (fcntl)", ["fcntl"]),
    ("store: SQLite CPU (statements, pages, log checksums)", ["libsqlite3", "sqlite3"]),
    ("network: send (responses over loopback TCP)", ["sendmsg", "writev", "__libc_send"]),
    ("network: receive", ["recvmsg", "readv", "__libc_recv", "tcp_recvmsg"]),
    ("network: epoll wait", ["epoll_wait"]),
    ("thread hand-offs (futex, scheduling)", ["futex", "__schedule", "sched_yield"]),
    ("tile check and decode", ["check_tile_exr"]),
    ("tile paste into the job image", ["::paste"]),
    ("scheduler: pick_job and leasable tiles (fair-share candidates)", ["pick_job", "leasable_now", "leasable_tiles"]),
    ("scheduler: the rest of its operations", ["LeaseFlow::", "FarmState::", "Scheduler::"]),
    ("change log (rows for the store)", ["ChangeLog::"]),
    ("JSON (nlohmann)", ["nlohmann"]),
    ("logging (spdlog)", ["spdlog", "fmt::"]),
    ("event bus / SSE", ["EventBus", "FarmEvents"]),
    ("worker secret check", ["worker_secret", "sha256"]),
    ("allocation (malloc/free)", ["malloc", "cfree", "_int_free", "unlink_chunk"]),
    ("memcpy/memset", ["memmove", "memset", "memcpy"]),
    ("HTTP parse/serialize (Beast)", ["beast::http"]),
]


def samples(lines):
    """Yields each sample's call stack (its frames' text, leaf first)."""
    stack = None
    for line in lines:
        if not line.strip():
            if stack:
                yield stack
            stack = None
        elif line[0] not in " \t":
            if stack:
                yield stack
            stack = []
        elif stack is not None:
            stack.append(line.strip())
    if stack:
        yield stack


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", help="perf script output (default: standard input)")
    ap.add_argument("--ms-per-tile", type=float, default=0.0, help="CPU ms per tile, to give each share in ms")
    args = ap.parse_args()
    source = open(args.file, encoding="utf-8", errors="replace") if args.file else sys.stdin
    counts = collections.Counter()
    total = 0
    for stack in samples(source):
        total += 1
        text = "\n".join(stack)
        for name, keys in COSTS:
            if any(k in text for k in keys):
                counts[name] += 1
                break
        else:
            counts["other"] += 1
    if not total:
        sys.exit("perf_breakdown: no samples")
    print(f"{total} samples")
    for name, n in counts.most_common():
        share = n / total
        ms = f"  {share * args.ms_per_tile:.3f} ms/tile" if args.ms_per_tile else ""
        print(f"{100 * share:5.1f}%{ms}  {name}")


if __name__ == "__main__":
    main()
