"""``comems4build reproduce``: the paper's table beside ours, its findings and the interpretation study."""

from __future__ import annotations

import argparse
import sys

from .options import COUNT, real


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``reproduce``."""
    parser.add_argument("--out", metavar="DIR", required=True, help="output directory (reproduce.md, reproduce.html, "
                                                     "reproduce.json, runs/)")
    parser.add_argument("--no-study", action="store_true",
                        help="only the three default runs, the table and the findings (no interpretation study)")
    parser.add_argument("--only", default=None, metavar="KEY[,KEY...]",
                        help="study only these ambiguities of config/reproduce.yaml")
    parser.add_argument("--jobs", type=COUNT, default=None, metavar="N",
                        help="parallel runs, integer >= 1 (default: CPU count)")
    parser.add_argument("--weeks", type=real(0, 12, lo_open=True), default=None, metavar="N",
                        help="run length in weeks, in (0, 12] (default 12, the paper's; shorter runs are quick "
                             "checks that do not compare with the paper's table)")


def run(args: argparse.Namespace) -> int:
    """Run the reproduction and print where the report is."""
    from ..fileio import check_out_dir
    from ..report.reproduce import reproduce

    check_out_dir(args.out)
    only = [k for k in args.only.split(",") if k] if args.only else None
    bar = None
    if sys.stderr.isatty():
        from tqdm import tqdm

        bar = tqdm(total=0, desc="reproduce", unit="run", file=sys.stderr)

    def progress(done: int, total: int, name: str) -> None:
        if bar is not None:
            bar.total = total
            bar.set_postfix_str(name)
            bar.update(done - bar.n)

    try:
        res = reproduce(args.out, with_study=not args.no_study, jobs=args.jobs, weeks=args.weeks, only=only,
                        progress=progress)
    finally:
        if bar is not None:
            bar.close()
    held = sum(c["held"] for c in res.checks)
    print(f"median relative error {100 * res.median_rel_error:.1f} %; cost ratios "
          + ", ".join(f"{k} {v:.2f}" for k, v in res.ratios.items())
          + f"; findings held {held} of {len(res.checks)}")
    print(f"{res.runs_made} runs in {res.wall_s:.0f} s; wrote {res.markdown}, {res.html}, {res.json}")
    return 0
