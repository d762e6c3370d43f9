#!/usr/bin/env python3
"""The suite's measured test durations: the fast lane's slow list and the slowest tests.

Reads the ``--durations=0`` report of a full pytest run (the lines ``12.34s call
test/test_x.py::test_y``) and

- writes ``test/slow_tests.txt`` (``--write``): every test whose set-up or call took at least
  ``--threshold`` seconds, and the whole module where a set-up took that long (a module- or
  session-scoped fixture: its other tests would pay for it in the fast lane);
- prints the slowest ``--top`` tests (set-up, call and teardown summed) as a Markdown table.

Usage::

    bash tools/test.sh --durations=0 | tee full.log
    .venv/bin/python tools/test_durations.py full.log --write
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SLOW_LIST = ROOT / "test" / "slow_tests.txt"
LINE = re.compile(r"^\s*(\d+(?:\.\d+)?)s\s+(setup|call|teardown)\s+(\S+)\s*$")


def read_durations(log: Path) -> dict[str, dict[str, float]]:
    """Durations per test id and phase [s] from a pytest ``--durations`` report.

    Parameters
    ----------
    log : pathlib.Path
        A file holding pytest's output.

    Returns
    -------
    dict
        ``{nodeid: {"setup": s, "call": s, "teardown": s}}`` (phases not listed are absent).
    """
    out: dict[str, dict[str, float]] = defaultdict(dict)
    for line in log.read_text(encoding="utf-8", errors="replace").splitlines():
        m = LINE.match(line)
        if m:
            out[m.group(3)][m.group(2)] = float(m.group(1))
    if not out:
        raise SystemExit(f"{log}: no '--durations' lines (run pytest with --durations=0)")
    return dict(out)


def slow_entries(durations: dict[str, dict[str, float]], threshold_s: float) -> list[tuple[str, float]]:
    """Tests and modules for the slow list with the time that put them there [s]."""
    entries: dict[str, float] = {}
    for nodeid, phases in durations.items():
        module = nodeid.split("::", 1)[0]
        if phases.get("setup", 0.0) >= threshold_s:
            entries[module] = max(entries.get(module, 0.0), phases["setup"])
        if phases.get("call", 0.0) >= threshold_s:
            entries[nodeid] = phases["call"]
    modules = {k for k in entries if "::" not in k}
    return sorted(((k, v) for k, v in entries.items() if "::" not in k or k.split("::", 1)[0] not in modules),
                  key=lambda kv: kv[0])


def main(argv: list[str] | None = None) -> int:
    """Command line: see the module docstring."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    ap.add_argument("log", type=Path, help="pytest output with a --durations=0 report")
    ap.add_argument("--threshold", type=float, default=3.0, help="seconds from which a test is slow (3)")
    ap.add_argument("--top", type=int, default=20, help="slowest tests to print (20)")
    ap.add_argument("--write", action="store_true", help=f"write {SLOW_LIST.relative_to(ROOT)}")
    args = ap.parse_args(argv)
    durations = read_durations(args.log)
    total = sorted(((sum(p.values()), k) for k, p in durations.items()), reverse=True)
    print("| test | s |\n|---|---:|")
    for seconds, nodeid in total[: args.top]:
        print(f"| `{nodeid}` | {seconds:.0f} |")
    entries = slow_entries(durations, args.threshold)
    if args.write:
        lines = [
            "# Tests (test/x.py::name) and whole modules (test/x.py: a fixture's set-up took that long)",
            f"# measured at {args.threshold:g} s or more; the fast lane (tools/test.sh --quick) leaves them out.",
            "# Written by tools/test_durations.py from a full run's --durations=0 report.",
        ]
        lines += [f"{k}  # {v:.1f} s" for k, v in entries]
        SLOW_LIST.write_text("\n".join(lines) + "\n", encoding="utf-8")
        print(f"{SLOW_LIST.relative_to(ROOT)}: {len(entries)} entries", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
