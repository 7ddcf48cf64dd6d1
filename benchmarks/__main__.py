"""``python -m benchmarks [NAME ...]``: run every ``bench_*.py`` module's ``main()`` (or the named
ones). Each prints one table and writes ``benchmarks/results/<name>.json``."""

from __future__ import annotations

import importlib
import pkgutil
import sys
from pathlib import Path


def main(argv: list[str]) -> int:
    here = Path(__file__).parent
    names = sorted(m.name for m in pkgutil.iter_modules([str(here)])
                   if m.name.startswith("bench_"))
    wanted = [a if a.startswith("bench_") else f"bench_{a}" for a in argv]
    unknown = sorted(set(wanted) - set(names))
    if unknown:
        sys.stderr.write(f"benchmarks: unknown {', '.join(unknown)}; have {', '.join(names)}\n")
        return 2
    for name in wanted or names:
        print(f"\n== {name} ==", flush=True)
        importlib.import_module(f"benchmarks.{name}").main()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
