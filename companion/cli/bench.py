"""``companion bench paper|perf|tracking``: each benchmark registers its own sub-command."""

from __future__ import annotations

import importlib

BENCH_MODULES = (
    "companion.bench.paper",
    "companion.bench.perf",
    "companion.bench.tracking",
)


def register(subparsers) -> None:
    parser = subparsers.add_parser("bench", help="benchmarks: paper table, performance, tracking fronts")
    bench_sub = parser.add_subparsers(dest="bench", metavar="BENCH")
    for name in BENCH_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as err:  # TODO(integration): remove once every bench exists
            if err.name != name:
                raise
            continue
        module.register(bench_sub)
    parser.set_defaults(func=lambda args: parser.print_help() or 2)
