"""Robustness sweeps: ``sweep`` (Monte Carlo or grid over model tolerances, on Dask.distributed)."""

from __future__ import annotations

import argparse
import csv
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..units import DURATION, SEED, Spec
from .common import (
    JOBS,
    check_writable,
    dropped_notes,
    earlier_plots,
    quiet_unawaited_coroutines,
    remove_earlier_plots,
    save_figure,
    sigterm_as_ctrl_c,
    spec_arg,
    warn,
    write_json,
    write_whole,
    yang_sun_notes,
)

__all__ = ["register"]

_COUNT = Spec(unit="1", doc="runs", low=1, high=10_000_000, integer=True)

_EPILOG = """\
KEY=SPEC (numbers in SI; a trailing x means times the nominal value):
  a:b or uniform(a,b)      uniform (grid: N points a..b)        backlash=0.5x:2x
  loguniform(a,b)          log-uniform (grid: geometric points) mesh_stiffness=loguniform(0.5x,2x)
  normal(m,s[,lo,hi])      Gaussian, truncated to [lo,hi]       coulomb_friction2=normal(0.2,0.05,0,inf)
  lognormal(m,s[,lo,hi])   median m, log-std s                  load_inertia=lognormal(5e-3,0.2)
  a,b,c                    a list (one value fixes the key)     load_noise=0,1e-6,2e-6
KEY: a model key (backlash, mesh_stiffness, damping_ratio, coulomb_friction1/2, viscous_friction1/2,
motor_inertia, load_inertia, load_torque, torque_limit, motor_noise, load_noise, ...; a train's stage key
sets every stage), estimate (the controller's backlash estimate [m]; x scales the nominal one) or
estimate_error (relative error of the estimate against each run's true backlash).

The controller is designed once on the nominal model and run on every perturbed plant. A draw outside a
key's range is an error before any run (truncate the distribution instead). Each run's "command" is the
`gearctl track` line that reproduces it alone. --scheduler tcp://HOST:PORT (or DASK_SCHEDULER_ADDRESS) runs
on a cluster started with `dask scheduler` and `dask worker tcp://HOST:PORT --nthreads 1`.
"""


def _fmt_urad(q: dict[str, float] | None) -> str:
    if not q:
        return "no run ran to its end"
    return (f"median {q['median'] * 1e6:.4g}, p95 {q['p95'] * 1e6:.4g}, p99 {q['p99'] * 1e6:.4g}, "
            f"max {q['max'] * 1e6:.4g} (min {q['min'] * 1e6:.4g})")


def _text(result: Any) -> list[str]:
    s, st, eng = result.summary, result.settings, result.engine
    ranges = any(v.kind != "list" for v in result.vary)
    points = f" of {st['points']} points per key" if ranges else ""
    mode = f"grid{points}" if st["grid"] else f"Monte Carlo, seed {st['seed']}"
    lines = [f"{st['model']}: {st['controller']} designed on the nominal model, {s['runs']} runs ({mode}) on the "
             f"{st['plant']} plant, {st['reference']} reference, {st['duration']:g} s each; {eng['where']}, "
             f"{eng['wall_time']:.1f} s"]
    for v in result.vary:
        lines.append(f"  varied                 {v.describe()}")
    if eng.get("resumed"):
        res = eng["resumed"]
        lines.append(f"  resumed                from {res['from'] or 'a previous sweep'}: {res['reused']} runs reused, "
                     f"{res['rerun']} rerun")
    if result.missing:
        why = "interrupted" if eng.get("interrupted") else "the cluster failed"
        lines.append(f"  missing                {len(result.missing)} of {st['runs']} runs did not finish ({why}): "
                     f"the figures are the {s['runs']} others'")
    lines.append(f"  RMS error [urad]       {_fmt_urad(s['rms_error'])}")
    lines.append(f"  max error [urad]       {_fmt_urad(s['max_error'])}")
    f = s["fractions"]
    lines.append(f"  loop health            limit cycle {f['limit_cycle']:.1%}, saturated {f['saturated']:.1%}, "
                 f"impact rate high {f['impact_rate_high']:.1%}, not following {f['not_following']:.1%}, "
                 f"falling back {f['falling_back']:.1%}, chattering {f['chattering']:.1%}, "
                 f"diverged {f['diverged']:.1%} "
                 f"(failed {s['failed']})")
    w = s["worst"]
    if w is not None:
        from ..sweep import Scale

        shown = ", ".join(f"{k} = {v:.4g}{'x' if isinstance(v, Scale) else ''}" for k, v in w["params"].items()) \
            or "nominal"
        lines.append(f"  worst                  run {w['index']} ({shown}): RMS {w['rms_error'] * 1e6:.4g} urad, "
                     f"max {w['max_error'] * 1e6:.4g} urad")
        lines.append(f"                         {w['command']}")
    for k, sens in s["sensitivity"].items():
        rho, el = sens["rank_correlation"], sens["elasticity"]
        lines.append(f"  sensitivity of RMS     {k}: rank correlation "
                     f"{'-' if rho is None else f'{rho:+.2f}'}" + ("" if el is None else f", elasticity {el:+.3g}"))
    iso = (("reversal_value", "reversal B"), ("repeatability", "repeatab. R"), ("accuracy", "accuracy A"))
    for k, label in iso:
        q = s.get(k)
        if q:
            lines.append(f"  ISO 230-2 {label:<13}median {q['median'] * 1e6:.4g} urad, max {q['max'] * 1e6:.4g} urad")
    return lines


def _markdown(result: Any, plots: list[tuple[str, str]]) -> str:
    s, st = result.summary, result.settings
    md = ["# gearctl sweep", "", "```", *_text(result), "```", ""]
    md += ["| figure | min | p5 | median | p95 | p99 | max |", "|---|---:|---:|---:|---:|---:|---:|"]
    for k in ("rms_error", "max_error"):
        q = s[k]
        if q:
            md.append(f"| {k.replace('_', ' ')} [urad] | " + " | ".join(
                f"{q[c] * 1e6:.4g}" for c in ("min", "p5", "median", "p95", "p99", "max")) + " |")
    md += ["", "| health | fraction of runs |", "|---|---:|"]
    md += [f"| {k.replace('_', ' ')} | {v:.1%} |" for k, v in s["fractions"].items()]
    if s["sensitivity"]:
        md += ["", "| key | rank correlation with RMS | elasticity d ln RMS / d ln key |", "|---|---:|---:|"]
        for k, sens in s["sensitivity"].items():
            rho, el = sens["rank_correlation"], sens["elasticity"]
            md.append(f"| {k} | {'-' if rho is None else f'{rho:+.3f}'} | {'-' if el is None else f'{el:+.3g}'} |")
    w = s["worst"]
    if w is not None:
        md += ["", f"Worst run ({w['index']}): RMS {w['rms_error'] * 1e6:.4g} urad, max {w['max_error'] * 1e6:.4g} "
               f"urad; reproduce it alone with", "", "```", w["command"], "```"]
    if s["failures"]:
        md += ["", "Failed runs (first ten):", ""]
        md += [f"- run {r['index']}: {r['message']} (`{r['command']}`)" for r in s["failures"]]
    md += ["", f"Table of every run: [runs.csv](runs.csv). Settings: {st['runs']} runs, seed {st['seed']}, "
           f"vary {', '.join(f'{k}={v}' for k, v in st['vary'].items()) or 'nothing'}.", ""]
    md += [f"![{what}]({name})" for name, what in plots]
    return "\n".join(md) + "\n"


def _write_csv(result: Any, path: Path) -> None:
    head, rows = result.table()

    def cell(v: Any) -> Any:
        if v is None:
            return ""
        return repr(v) if isinstance(v, float) else v  # repr: the exact double, read back bit for bit

    def write(fh: Any) -> None:
        w = csv.writer(fh, lineterminator="\n")  # Unix lines: `cut` and `awk` see no \r
        w.writerow(head)
        for r in rows:
            w.writerow([cell(v) for v in r])

    write_whole(path, write)


#: The plots a sweep writes into its --out folder (an earlier sweep's that this one does not write are removed).
_SWEEP_PLOTS = ("histogram.png", "map.png", "error_vs_*.png")


def _write_out(result: Any, out: Path) -> list[str]:
    """Write runs.csv, the plots and summary.md into ``out``; return the earlier sweep's plots removed there."""
    from ..plots import plot_sweep_histogram, plot_sweep_map, plot_sweep_scatter

    earlier = earlier_plots(out / "summary.md", "# gearctl sweep", _SWEEP_PLOTS)
    try:
        out.mkdir(parents=True, exist_ok=True)
        _write_csv(result, out / "runs.csv")
    except OSError as exc:
        raise InputError(f"cannot write {out}: {exc.strerror}") from None
    plots: list[tuple[str, str]] = []
    ok = any(r["status"] == "ok" for r in result.runs)
    if ok:
        save_figure(plot_sweep_histogram(result), str(out / "histogram.png"))
        plots.append(("histogram.png", "RMS and max error over the runs"))
        for k in result.keys:
            save_figure(plot_sweep_scatter(result, k), str(out / f"error_vs_{k}.png"))
            plots.append((f"error_vs_{k}.png", f"error against {k}"))
        if result.settings["grid"] and len(result.keys) == 2 and not result.missing:
            save_figure(plot_sweep_map(result), str(out / "map.png"))
            plots.append(("map.png", f"RMS error over {result.keys[0]} and {result.keys[1]}"))
    try:
        write_whole(out / "summary.md", _markdown(result, plots))
    except OSError as exc:
        raise InputError(f"cannot write {out / 'summary.md'}: {exc.strerror}") from None
    return remove_earlier_plots(out, earlier, [name for name, _ in plots])


#: The options that set what a sweep's runs are: a resumed sweep (--resume) takes them all from its JSON.
_SETTINGS_FLAGS = (("model", "MODEL"), ("controller", "CONTROLLER"), ("vary", "--vary"), ("runs", "--runs"),
                   ("grid", "--grid"), ("plant", "--plant"), ("reference", "--reference"), ("duration", "--duration"),
                   ("seed", "--seed"), ("precision", "--precision"))
#: Their defaults (None in the parser, so that one given with --resume is seen).
_DEFAULTS = {"model": "shing1993_servo", "controller": "deadzone_inverse", "plant": "improved", "reference": "sine",
             "seed": 0}


def _resumed_keys(path: str) -> list[str]:
    """The varied keys of the sweep ``path`` holds, for the --out check before the runs (none where it cannot be
    read: :func:`gearctl.sweep.resume` then says what is wrong with it)."""
    import json

    try:
        with open(path, encoding="utf-8") as fh:
            vary = json.load(fh)["settings"]["vary"]
        return [str(k) for k in vary]
    except (OSError, ValueError, KeyError, TypeError):
        return []


def _cmd_sweep(args: argparse.Namespace) -> int:
    import logging

    from .. import sweep as sweeps
    from ..sweep import SweepIncomplete, SweepInterrupted

    quiet_unawaited_coroutines()  # what a Ctrl-C leaves of Dask's requests (see there)
    if args.resume is not None:  # every setting is the previous sweep's: one given here would change the runs
        given = [flag for key, flag in _SETTINGS_FLAGS  # (is: --seed 0 is given, and 0 == False)
                 if getattr(args, key) is not None and getattr(args, key) is not False]
        if given:
            raise InputError(f"--resume {args.resume} and {', '.join(given)}: a resumed sweep takes every setting "
                             f"from the previous sweep's JSON (another would change what its runs are); give only "
                             f"--workers, --scheduler, --batch, --json, --out and --quiet", field="resume")
    else:
        for key, value in _DEFAULTS.items():
            if getattr(args, key) is None:
                setattr(args, key, value)
    if (args.scheduler or os.environ.get("DASK_SCHEDULER_ADDRESS")) and args.workers:
        warn("sweep", ["--workers sizes the local cluster; with --scheduler (or DASK_SCHEDULER_ADDRESS) the "
                       "cluster's own workers run the sweep"])
    from ..catalog import load_model
    from ..closedloop import check_loop_memory
    from ..plant import build_plant
    from ..runs import DEFAULT_DURATION

    if args.resume is None:
        # a run that would not fit in memory is refused before the sweep, not reported as every run failed (here at
        # the catalog's 1 ms loop, before the controller is read; plan_sweep checks again at the controller's sample
        # time)
        dur = args.duration if args.duration is not None else DEFAULT_DURATION[args.reference]
        check_loop_memory(build_plant(load_model(args.model)), dur)
    # where the results go is checked before the runs: a sweep of hours must not end unable to write them
    to_stdout = args.json == "-"  # the JSON on standard output, the summary then on standard error
    if args.json and not to_stdout:
        check_writable(args.json, key="json")
    if args.out:
        keys = ([text.partition("=")[0].strip() for text in args.vary or ()] if args.resume is None
                else _resumed_keys(args.resume))
        check_writable(args.out, directory=True, key="out", files=["runs.csv", "summary.md", "histogram.png", "map.png",
                                                                     *(f"error_vs_{k}.png" for k in keys)])
    bar: Any = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if args.quiet:
            return
        if bar is None:  # made once the total is known (a bar of total 0 showed "0run")
            from tqdm import tqdm

            bar = tqdm(total=total, desc="gearctl sweep", unit="run", file=sys.stderr, leave=False, disable=None)
        bar.total = total
        bar.update(done - bar.n)

    # the Dask client's own log (a scheduler lost mid-sweep: 35 lines and two tracebacks before the one line that
    # says it) stays quiet at the command line; the sweep's error says what happened
    import distributed  # noqa: F401 - its loggers (distributed.client, ...) set their own levels on import

    # the client's side of a lost connection only: a local cluster's nannies log in this process too, and their word
    # on a worker killed for its memory must stay
    quiet = [lg for name, lg in logging.root.manager.loggerDict.items()
             if name.startswith(("distributed.client", "distributed.comm", "distributed.core", "distributed.batched",
                                 "distributed.utils")) and isinstance(lg, logging.Logger)]
    levels = [lg.level for lg in quiet]
    for lg in quiet:
        lg.setLevel(logging.CRITICAL + 1)
    unfinished: SweepIncomplete | SweepInterrupted | None = None
    try:
        with sigterm_as_ctrl_c():
            if args.resume is not None:
                result = sweeps.resume(args.resume, workers=args.workers, scheduler=args.scheduler, batch=args.batch,
                                       progress=progress)
            else:
                result = sweeps.sweep(args.model, args.controller, vary=args.vary or [], runs=args.runs,
                                      grid=args.grid, reference_kind=args.reference, duration=args.duration,
                                      seed=args.seed, plant=args.plant, precision=args.precision,
                                      workers=args.workers, scheduler=args.scheduler, batch=args.batch,
                                      progress=progress)
    except (SweepIncomplete, SweepInterrupted) as exc:  # the cluster failed mid-sweep, or Ctrl-C: what finished is
        unfinished, result = exc, exc.result           # written as a whole sweep's is (a second Ctrl-C ends it)
    finally:
        for lg, lv in zip(quiet, levels, strict=True):
            lg.setLevel(lv)
        if bar is not None:
            bar.close()
    if args.json and not to_stdout:
        try:
            Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            write_whole(args.json, lambda fh: write_json(fh, result.as_dict()))
        except OSError as exc:
            raise InputError(f"cannot write {args.json}: {exc.strerror}") from None
    if args.out:
        gone = _write_out(result, Path(args.out))
        if gone:
            warn("sweep", [f"--out {args.out}: removed {', '.join(gone)}, which an earlier sweep wrote there and this "
                           f"one does not (its keys or runs differ)"], kind="note")
    # (a worker dropped before the cluster failed or the Ctrl-C is said too: it was only in the JSON)
    warn("sweep", dropped_notes(result.engine.get("dropped", ())), kind="note")
    if unfinished is not None:  # the files, as a whole sweep's with "missing"; the summary; then the one error line
        print("\n".join(_text(result)), file=sys.stderr if to_stdout else sys.stdout)
        if to_stdout:
            write_json(sys.stdout, result.as_dict())
            print()
        sys.stdout.flush()
        wrote = [f"--json {args.json}" if args.json and not to_stdout else "",
                 f"--out {args.out}" if args.out else "", "the JSON on standard output" if to_stdout else ""]
        where = " and ".join(filter(None, wrote)) or "the summary above (no --json or --out given)"
        if isinstance(unfinished, SweepInterrupted):  # one line, and the shell's code for SIGINT (128 + 2)
            print(f"gearctl sweep: {unfinished}; the finished runs are in {where}", file=sys.stderr)
            return 130
        raise InputError(f"{unfinished}; the finished runs are in {where}", field=unfinished.field)
    design = result.settings.get("design", {})
    warn("sweep", [f"{design.get('name')}: {n}" for n in design.get("design_notes", ())], kind="note")
    warn("sweep", yang_sun_notes(load_model(result.settings["model"]), result.settings["plant"]), kind="note")
    if not result.settings["vary"]:
        warn("sweep", ["nothing varied (no --vary): every run is the nominal plant, the runs differ only in their "
                       "sensor-noise seeds"], kind="note")
    summary = sys.stderr if to_stdout else sys.stdout
    print("\n".join(_text(result)), file=summary)
    if result.summary["failed"]:
        warn("sweep", [f"{result.summary['failed']} of {result.summary['runs']} runs failed: see their message "
                       f"and command in the table"])
    if args.json and not to_stdout:
        print(f"  wrote {args.json} (JSON)")
    if args.out:
        print(f"  wrote {args.out}/runs.csv, summary.md and plots", file=summary)
    if to_stdout:  # written piece by piece: the whole text of a large sweep is more than its results (iter_json)
        # last: a reader that closes the pipe early (`| head`) ends the command quietly, and before, the --out
        # files and the summary, written after it, were lost with exit 0
        summary.flush()
        write_json(sys.stdout, result.as_dict())
        print()
    return 0


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    """Add the ``sweep`` command to the subparsers; return name -> function.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``gearctl`` parser's subparsers.

    Returns
    -------
    dict
        Command name -> the function that runs it (given the parsed arguments, it returns the exit code).
    """
    p = sub.add_parser("sweep", help="robustness sweep: one design against many perturbed plants (Dask)",
                       epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    # (the settings' defaults are None here, filled in by _cmd_sweep: one given with --resume is refused)
    p.add_argument("model", nargs="?", help="model (default shing1993_servo)")
    p.add_argument("controller", nargs="?", help="controller: catalog name or TOML path (default deadzone_inverse)")
    p.add_argument("--vary", action="append", metavar="KEY=SPEC",
                   help="a key and its tolerance (repeat for more); on a train a stage key sets every stage, "
                        "stageN.KEY (e.g. stage2.backlash=0.5x:2x) stage N's alone")
    p.add_argument("--runs", type=spec_arg(_COUNT), help="Monte Carlo runs (default 100); with --grid, points per "
                                                         "range (default 5; 1: its midpoint)")
    p.add_argument("--grid", action="store_true", help="a full grid over the keys instead of Monte Carlo draws")
    p.add_argument("--plant", choices=("improved", "yang-sun", "tvms"),
                   help="true plant (default improved; the design is on the improved plant)")
    p.add_argument("--reference", choices=("sine", "step", "ramp", "move"),
                   help="reference (default sine)")
    p.add_argument("--duration", type=spec_arg(DURATION), help="simulated time of each run [s] (default per "
                                                               "reference: sine 3 s, step 2 s, ramp 1.5 s, move 1 s)")
    p.add_argument("--seed", type=spec_arg(SEED), help="seed of the draws and the sensor noise (default 0)")
    p.add_argument("--workers", "--jobs", dest="workers", type=spec_arg(JOBS),
                   help="processes of the local cluster (default: all cores; --jobs as in bench)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler, tcp://HOST:PORT (default DASK_SCHEDULER_ADDRESS, else a local "
                        "cluster)")
    p.add_argument("--batch", type=spec_arg(_COUNT),
                   help="runs per Dask task (default: about 0.5 s of work, at least 4 tasks per worker)")
    p.add_argument("--precision", action="store_true", help="also the ISO 230-2 test on each plant (slow)")
    p.add_argument("--json", metavar="FILE", help="write settings, summary and every run as JSON (- for standard "
                                                  "output; the summary then goes to standard error)")
    p.add_argument("--out", metavar="DIR", help="write runs.csv, plots and summary.md")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--resume", metavar="PREVIOUS.json",
                   help="rerun only the runs a sweep did not finish (its --json: interrupted, or the cluster failed), "
                        "every setting taken from it, and write the whole sweep (with --json, --out); MODEL, "
                        "CONTROLLER and the options that set the runs are refused with it")
    return {"sweep": _cmd_sweep}
