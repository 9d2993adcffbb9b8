"""``companion bench paper|perf|tracking``: each benchmark registers its own sub-command."""

from __future__ import annotations

import importlib

BENCH_MODULES = (
    "companion.bench.paper",
    "companion.bench.perf",
    "companion.bench.tracking",
    "companion.bench.sitl",
    "companion.bench.bound",
    "companion.bench.fronts",
)


def register(subparsers) -> None:
    parser = subparsers.add_parser("bench", help="benchmarks: paper table, performance, tracking fronts")
    bench_sub = parser.add_subparsers(dest="bench", metavar="BENCH")
    for name in BENCH_MODULES:
        importlib.import_module(name).register(bench_sub)
    parser.set_defaults(func=lambda args: parser.print_help() or 2)
