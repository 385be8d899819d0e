"""``rigctl analyse RUN.h5|RUN.csv|FOLDER... [--out DIR] [--json]``: analyse runs as the paper does.

Writes ``DIR/index.html`` (figures as PNG next to it) and ``DIR/analysis.json`` with every number;
``--json`` also prints that JSON on stdout (and no progress bar). A folder is a campaign: every run
is analysed, and runs at several normal forces get the force-sweep summary (Figs. 10-11). What a run
lacks (frames, frame times, probe range, a run cut short) is said in the report, never a traceback.
See docs/analysis.md. Unreadable files raise ``DataError`` naming the file (exit 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = subparsers.add_parser(
        "analyse", help="analyse runs as the paper does (report + JSON)",
        description="Stages, stick/slip cycles, friction coefficients, stiffness, repeatability "
                    "and the force-sweep summary of recorded, simulated or imported runs.",
    )
    p.add_argument("data", nargs="+", metavar="RUN",
                   help="run files (.h5, .csv) or folders of them (a campaign)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="report folder (default: analysis_<first run name> next to it)")
    p.add_argument("--json", action="store_true", help="print analysis.json on stdout")
    p.set_defaults(func=run_analyse)


def _default_out(first: str) -> Path:
    src = Path(first)
    return src.parent / f"analysis_{src.stem if src.is_file() else src.name}"


def run_analyse(args: argparse.Namespace) -> int:
    from rigctl.analysis.pipeline import analyse_campaign
    from rigctl.analysis.report import campaign_json, write_report
    from rigctl.io.outputs import check_output_folder
    from rigctl.records.progress import Progress

    progress = Progress(False if args.json else None)
    out = args.out if args.out is not None else _default_out(args.data[0])
    check_output_folder(out, "--out")
    result = analyse_campaign(args.data, progress=progress)
    index, js = write_report(result, out, progress)
    if args.json:
        print(campaign_json(result))
    else:
        for ra in result.runs:
            print(f"{ra.name}: {len(ra.mechanics.passes)} pass(es), "
                  f"{sum(p.cycles.n for p in ra.mechanics.passes)} cycles, "
                  f"{len(ra.notes)} note(s)")
        for note in result.notes:
            print(f"note: {note}")
        print(f"report: {index}")
        print(f"numbers: {js}")
    sys.stdout.flush()
    return 0
