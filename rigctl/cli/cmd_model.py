"""Model workbench commands: ``rigctl model compare`` and ``rigctl model diagnose``.

* ``model compare DATA... [--base paper|classic] [--effects a,b] [--effect-file F.py]
  [--no-fit] [--json] [--report DIR]``: identify the model on the runs (files or folders = a
  campaign), simulate every run on its measured stage position and normal force, and report the
  event-aware error, per-feature errors, parameters with uncertainties and where the model fails.
* ``model diagnose DATA... [--base ...] [--effects ...] [--effect-file F.py] [--candidates a,b]
  [--auto] [--workers N] [--timeout S] [--max-time S] [--json] [--report DIR]``: identify the
  model, screen every candidate effect of the library and the plug-ins (and pairs), fit the
  promising ones fully, rank them by evidence (BIC over slip events) and give the verdict;
  ``--auto`` adds the best significant effect and repeats, then removes what does not earn its
  place.

See docs/workbench.md. Data problems raise ``DataError`` naming the file (exit 2).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from rigctl.cli.cmd_simulate import add_plugins_argument
from rigctl.errors import UsageError
from rigctl.io.json_values import jsonable
from rigctl.io.outputs import check_output_folder

# numpy, scipy, the engine and matplotlib are imported inside the commands.


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("data", nargs="+", metavar="DATA",
                   help="run files (.csv, .h5) or folders of them (a campaign)")
    p.add_argument("--base", default="paper", choices=("paper", "classic"),
                   help="base model (default: paper)")
    p.add_argument("--effects", default="", metavar="A,B",
                   help="effects to add to the base (comma-separated names)")
    p.add_argument("--effect-file", action="append", default=[], metavar="F.py",
                   help="plug-in effect file (repeatable); its effects become available")
    p.add_argument("--json", action="store_true",
                   help="print the result as JSON on stdout (progress stays on stderr)")
    p.add_argument("--quiet", action="store_true", help="print no progress on stderr")
    p.add_argument("--report", type=Path, metavar="DIR", help="write an HTML + PNG report here")
    add_plugins_argument(p)


def register(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    model = subparsers.add_parser(
        "model", help="compare the physics model with measurements and diagnose what is missing",
        description="Model workbench: compare, see where it fails, rank missing effects.",
    )
    sub = model.add_subparsers(dest="model_command", metavar="ACTION",
                               parser_class=type(model))
    sub.required = True
    cmp = sub.add_parser("compare", help="identify the model and compare it with the data",
                         description="Identify, simulate and compare model and measurement.")
    _add_common(cmp)
    cmp.add_argument("--no-fit", action="store_true",
                     help="compare with the parameter values as given (no identification)")
    cmp.add_argument("--workers", type=int, default=None, metavar="N",
                     help="parallel processes evaluating the search (default: the CPUs)")
    cmp.set_defaults(func=run_compare)

    dia = sub.add_parser("diagnose", help="rank candidate effects by evidence",
                         description="Screen each candidate effect, fit the promising ones and "
                                     "rank them; --auto chooses the effects.")
    _add_common(dia)
    dia.add_argument("--candidates", default="", metavar="A,B",
                     help="only these candidates (default: the whole library and plug-ins)")
    dia.add_argument("--auto", action="store_true",
                     help="add the best significant effect, re-identify, repeat")
    dia.add_argument("--workers", type=int, default=None, metavar="N",
                     help="parallel processes (default: the CPUs)")
    dia.add_argument("--timeout", type=float, default=300.0, metavar="S",
                     help="time limit of one candidate fit in seconds (default 300): a fit that "
                          "reaches it ends with its best point so far")
    dia.add_argument("--max-time", type=float, default=None, metavar="S",
                     help="time limit of the whole run in seconds (default 540; 0: none); each "
                          "fit gets its share of the time left, and at the limit the run ends "
                          "with the model it has and says so")
    dia.set_defaults(func=run_diagnose)


def _names(text: str) -> list[str]:
    return [n.strip() for n in text.split(",") if n.strip()]


def _choice(args: argparse.Namespace) -> Any:
    from rigctl.workbench.model_choice import ModelChoice, registry_for

    files = tuple(str(Path(f).resolve()) for f in args.effect_file)
    for f in files:
        if not Path(f).is_file():
            raise UsageError(f"--effect-file {f}: no such file")
    registry = registry_for(files)
    effects = _names(args.effects)
    for name in effects:
        if name not in registry:
            raise UsageError(f"unknown effect '{name}' (known: {', '.join(sorted(registry))})")
    choice = ModelChoice(args.base, tuple(effects), {}, files)
    choice.build()  # parameter problems surface here, as one line
    return choice


def _load(args: argparse.Namespace) -> list[Any]:
    """The runs named, long records cut into windows (rigctl.records.long_records)."""
    from rigctl.io.load import load_runs
    from rigctl.records.long_records import window_long_runs

    return window_long_runs(load_runs([str(p) for p in args.data]))


def _progress(args: argparse.Namespace) -> Any:
    """Progress lines on stderr (with ``--json`` too: stdout holds the JSON alone), unless
    ``--quiet``."""
    if args.quiet:
        return None
    return lambda msg: print(msg, file=sys.stderr, flush=True)


def run_compare(args: argparse.Namespace) -> int:
    from rigctl.workbench.compare import compare
    from rigctl.workbench.parallel import default_workers
    from rigctl.workbench.report import write_compare_report

    if args.workers is not None and args.workers < 1:
        raise UsageError("--workers must be at least 1")
    choice = _choice(args)
    if args.report:
        check_output_folder(args.report, "--report")
    runs = _load(args)
    cmp = compare(runs, choice, identify=not args.no_fit, progress=_progress(args),
                  workers=args.workers or default_workers())
    if args.report:
        path = write_compare_report(cmp, args.report)
        if not args.json:
            print(f"report: {path}")
    if args.json:
        print(json.dumps(jsonable(cmp.to_json()), indent=2))
        return 0
    _print_compare(cmp)
    return 0


def _print_compare(cmp: Any) -> None:
    from rigctl.records.feature_info import FEATURES

    n_model = sum(m.n for m in cmp.evaluation.events)
    print(f"model {cmp.fit.choice.label()}: error {cmp.fit.error:.3g} "
          f"({cmp.dataset.n_events} slip events in {len(cmp.dataset.runs)} run(s); "
          f"the model makes {n_model})")
    for note in cmp.dataset.notes:
        print(f"note: {note}")
    print("\nper-feature error (z: in units of the measured scatter; RMS/mean: model - measured)")
    for name, fe in cmp.errors.items():
        z = cmp.fit.feature_error.get(name, math.nan)
        print(f"  {FEATURES[name].phrase[:44]:44s} z {z:7.2f}   RMS {fe.rms:10.4g}  "
              f"mean {fe.mean:10.4g} {fe.unit}")
    print("\nparameters")
    for r in cmp.parameter_rows():
        if not r["fitted"]:
            continue
        sig = f" +- {r['sigma']:.3g}" if r["sigma"] is not None else ""
        flag = "" if r["determined"] else "   <- not determined by these data"
        print(f"  {r['name']:32s} {r['value']:.5g}{sig} {r['unit']}{flag}")
    print("\nwhere it fails")
    for s in cmp.discrepancies or ["no structured discrepancy above the scatter"]:
        print(f"  - {s}")


def run_diagnose(args: argparse.Namespace) -> int:
    from rigctl.records.dataset import prepare_dataset
    from rigctl.workbench.compare import compare
    from rigctl.workbench.diagnose import diagnose
    from rigctl.workbench.model_choice import candidate_effects, registry_for
    from rigctl.workbench.report import write_diagnose_report

    if args.workers is not None and args.workers < 1:
        raise UsageError("--workers must be at least 1")
    if not args.timeout > 0:
        raise UsageError("--timeout must be positive")
    max_run_s = _max_time(args)
    choice = _choice(args)
    candidates = _names(args.candidates) or candidate_effects(choice)
    known = registry_for(choice.effect_files)
    for name in candidates:
        if name not in known:
            raise UsageError(f"unknown candidate '{name}' (known: {', '.join(sorted(known))})")
    if not candidates:
        raise UsageError("no candidate effects left to try")
    if args.report:
        check_output_folder(args.report, "--report")
    runs = _load(args)
    dataset = prepare_dataset(runs)
    progress = _progress(args)
    diag = diagnose(dataset, choice, candidates=candidates, auto=args.auto,
                    workers=args.workers, progress=progress, timeout_s=args.timeout,
                    max_run_s=max_run_s)
    if args.report:
        cmp = compare(runs, diag.first.model.choice, identify=False, dataset=dataset)
        cmp.fit = diag.first.model
        final_cmp = None
        if len(diag.steps) > 1:  # --auto added effects: show the final model too
            final_cmp = compare(runs, diag.final_model.choice, identify=False, dataset=dataset)
            final_cmp.fit = diag.final_model
        path = write_diagnose_report(diag, cmp, args.report, final_cmp)
        if not args.json:
            print(f"report: {path}")
    if args.json:
        print(json.dumps(jsonable(diag.to_json(args.auto)), indent=2))
        return 0
    _print_diagnosis(diag, args.auto)
    return 0


def _max_time(args: argparse.Namespace) -> float | None:
    """``--max-time``: the run's limit in seconds (None: none)."""
    from rigctl.workbench.run_deadline import DEFAULT_RUN_S

    if args.max_time is None:
        return DEFAULT_RUN_S
    if not (math.isfinite(args.max_time) and args.max_time >= 0):
        raise UsageError(f"--max-time must be 0 (no limit) or a positive number of seconds, "
                         f"not {args.max_time}")
    return args.max_time or None


def _print_diagnosis(diag: Any, auto: bool) -> None:
    from rigctl.workbench.ranking import VerdictKind

    r0 = diag.first
    print(f"model {r0.model.choice.label()}: baseline error {r0.model.error:.3g} "
          f"({diag.dataset.n_events} slip events)")
    print(f"protocols in the data: {', '.join(diag.protocols) or 'none recognised'}")
    width = max([26, *(len(s.effect) for s in r0.ranking)])
    print(f"\n  {'effect':{width}s}  error  reduction   delta BIC  signif.  explains")
    for s in r0.ranking:
        red = f"{s.error_reduction * 100:6.0f} %" if math.isfinite(s.error_reduction) else \
            "      -"
        dbic = f"{s.delta_bic:10.1f}" if math.isfinite(s.delta_bic) else "         -"
        print(f"  {s.effect:{width}s} {s.error:7.3g}  {red}  {dbic}  "
              f"{'yes' if s.significant else '   '}      {s.explains}")
    v = r0.verdict
    extra = f" ({', '.join(v.candidates)})" if v.candidates else ""
    print(f"\nverdict: {v.verdict}{extra}")
    if v.unexplained:
        print(v.unexplained)
    if v.suggest:
        print(f"to tell them apart: {v.suggest}")
        for run in v.runs:
            print(f"  {run['command']}    (reveals {run['reveals']})")
    if r0.discrepancies:
        print("\nwhere the model fails")
        for s in r0.discrepancies:
            print(f"  - {s}")
    if diag.time_limited and not auto:
        print(f"\nstopped: {diag.time_limited} (--max-time)")
    if auto:
        print("\nerror at each step (bar: error relative to the first model)")
        first = diag.steps[0].error
        prev = None
        for st in diag.steps:
            note = f" ({st.note})" if st.note else ""
            fall = f" {(st.error - prev) / prev * 100:+5.0f} %" if prev else "        "
            frac = st.error / first if first > 0 and math.isfinite(st.error) else 0.0
            bar = "#" * max(1, round(30 * min(frac, 1.0)))
            print(f"  {st.index}: {st.model:46s} error {st.error:8.3g}{fall}  {bar}{note}")
            prev = st.error
        last = diag.rounds[-1].verdict
        if last.kind is VerdictKind.INDISTINGUISHABLE:
            print(f"  stopped: the data cannot decide between {' and '.join(last.candidates)}")
            print(f"  to tell them apart: {last.suggest}")
            for run in last.runs:
                print(f"    {run['command']}    (reveals {run['reveals']})")
        elif diag.time_limited:
            print(f"  stopped: {diag.time_limited} (--max-time)")
        else:
            print("  stopped: " + ("nothing significant left" if last.kind is VerdictKind.NONE
                                   else "step limit reached"))
        if last.unexplained:
            print(f"  {last.unexplained}")
