"""`codegen`: the command line. It only parses arguments, calls the API function of the
subcommand (`build`, `check`, `inspect`, `verify`, `bench`, `network`: plain keyword arguments,
usable from Python) and presents the result; user errors become one line and a distinct exit code."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path

from dfeif_codegen import __version__
from dfeif_codegen.errors import CodegenError

DEFAULT_MODEL = "dc_motor_link"

# subcommand -> one-line help
COMMANDS = {
    "build": "generate the C module for a model into generated/<model>",
    "verify": "compile the generated C and compare it with the Python reference",
    "simulate": "run the closed-loop experiment (chapter tables, plots, JSON)",
    "scenario": "write a starting scenario for a model (q, P0, poles, noise)",
    "inspect": "show the derived flatness transform and discrete model",
    "bench": "measure build time, code size, stack and instruction counts",
    "network": "run nodes and master as separate processes over UDP on 127.0.0.1 through a seeded "
               "delay/drop relay and compare with the reference",
    "reproduce": "run every table and figure of docs/experiment.md (resumable) and render the document",
}


class StaleError(CodegenError):
    """`codegen build --check`: the folder on disk differs from a fresh build."""

    exit_code = 1
class _Parser(argparse.ArgumentParser):
    """argparse, but a bad option is one line and exit 2 (not a usage block)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message.splitlines()[0] if message else 'bad arguments'}\n")


def _model_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", nargs="?", default=DEFAULT_MODEL,
                   help=f"built-in model name or path to a .toml model file (default {DEFAULT_MODEL})")


def _filter_options(p: argparse.ArgumentParser, many: bool = False, nodes: int | None = None) -> None:
    """The build options of the estimator (repeatable where a command compares several)."""
    p.add_argument("--max-lag", type=int, default=32, metavar="N", help="late-measurement window (default 32)")
    p.add_argument("--nodes", type=int, default=nodes, metavar="M",
                   help="camera nodes (default: " + (f"{nodes})" if nodes else "the scenario's)"))
    kind = dict(action="append") if many else dict(default=None)
    p.add_argument("--oosm", choices=["retrodict", "replay"], **kind,
                   help="late-measurement method" + (" (repeatable)" if many else " (default replay)"))
    p.add_argument("--fusion", choices=["paper", "difference", "ci"], **kind,
                   help="master fusion rule" + (" (repeatable)" if many else " (default difference)"))
    p.add_argument("--predictor", choices=["held", "scheduled", "brunovsky"], default=None,
                   help="the filters' prediction and the control law: held (the canonical dynamics with the "
                        "applied u held; the default), scheduled (held, the covariance's transition taken at the "
                        "master's broadcast flat outputs) or brunovsky (the chapter's chain driven by v = F + G u; "
                        "the default with --oosm retrodict)")


def _build_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="generated", help="output folder (default generated)")
    p.add_argument("--precision", choices=["double", "float"], default="double",
                   help="the C's real type (default double)")
    _filter_options(p, nodes=2)
    p.add_argument("--ts", type=float, default=None, help="sampling period [s] (default: the model's)")
    p.add_argument("--disturbance", metavar="KIND", default=None,
                   help="random_walk, gauss_markov, integrated_random_walk or integrated_gauss_markov (d and its rate):"
                        " disturbance states per chain after the canonical state; densities after the chains' q")
    p.add_argument("--tau", type=float, default=None, metavar="S",
                   help="the gauss_markov disturbance's (integrated_gauss_markov: its rate's) time constant [s]")
    p.add_argument("--gate", type=float, default=None, metavar="SIGMAS", help="nodes refuse a measurement whose "
                   "innovation is over SIGMAS standard deviations (Mahalanobis) out: ERR_OUTLIER (default: no gate)")
    p.add_argument("--check", action="store_true",
                   help="write nothing: exit 0 if DIR/<model> equals a fresh build, 1 (listing the files) if "
                        "stale, 2 if missing")
    p.add_argument("--singular-rtol", type=float, default=1e-6, metavar="R",
                   help="control returns ERR_SINGULAR when |det G| < R * |det G(nominal)| (default 1e-6)")
    p.add_argument("--force", action="store_true",
                   help="build even where OUT/<model> holds files an earlier build did not write or "
                        "that were edited since (the build's own files are replaced, the others kept)")
    _budget_options(p)


def _budget_options(p: argparse.ArgumentParser) -> None:
    """--max-seconds and --max-memory: every command that derives a model takes them."""
    # None: the budget module's defaults (60 CPU-s, 2 GB), as for the dc.* keywords
    p.add_argument("--max-seconds", type=float, default=None, metavar="S",
                   help="CPU-time budget of the symbolic derivation in seconds (default 60)")
    p.add_argument("--max-memory", type=float, default=None, metavar="GB",
                   help="memory budget of the symbolic derivation in GB (default 2)")


def _budget(args: argparse.Namespace) -> dict:
    return dict(max_seconds=args.max_seconds, max_memory=args.max_memory)


def _verify_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--target", choices=["host", "cortex-m4f"], default="host",
                   help="where the C runs: this machine, or an emulated Cortex-M4F in QEMU (default host)")
    p.add_argument("--precision", choices=["double", "float"], default=None,
                   help="default: double on the host, float on cortex-m4f")
    p.add_argument("--sanitize", action="store_true", help="host: build with -fsanitize=address,undefined")
    p.add_argument("--scenario", default="paper",
                   help="'paper' or a scenario .toml to record (its first row with late frames; default paper)")
    p.add_argument("--inputs", choices=["recorded", "own"], default="recorded",
                   help="the filters predict with the recorded inputs v, which the recorded measurements "
                        "reflect (default), or with the v the C controller computes")
    _filter_options(p)
    p.add_argument("--gate", type=float, default=None, metavar="SIGMAS", help="the innovation gate, as build's")
    _budget_options(p)


def _simulate_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="paper", help="'paper' or a path to a scenario .toml (default paper)")
    p.add_argument("--runs", type=int, default=None, help="seeds to average over")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    _filter_options(p, many=True)
    p.add_argument("--reference", choices=["sinusoid", "seesaw", "trajectory"], action="append", help="(repeatable)")
    p.add_argument("--filters", action="append", metavar="LIST",
                   help="df,ekf,ukf,brunovsky,offsets,scheduled: also run these filters on the replay + "
                        "difference recordings (Table VI); offsets (estimating the [offsets] table's parameters) "
                        "and scheduled (its transition following the master's outputs) are reference only")
    p.add_argument("--param-error", metavar="SPREAD|NAME=REL,...", default=None,
                   help="model error, replacing the scenario's [model_error]: 0.2 draws each of the plant's "
                        "parameters per run within +-20%% of the model's; R=0.2,J=-0.1 fixed relative offsets; "
                        "0 the exact model (the filters and the controller keep the model's values)")
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--json", metavar="FILE", help="write every figure machine-readably ('-' for stdout)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--engine", choices=["c", "reference"], default="c",
                   help="closed loops in compiled C (default) or in the numpy reference")
    p.add_argument("--workers", type=int, default=None, metavar="N", help="local processes (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing Dask distributed cluster (extra 'cluster')")
    p.add_argument("--results", metavar="FILE", help="per-run results as JSON lines, written as runs finish")
    p.add_argument("--csv", metavar="FILE", help="per-run scalar results as CSV")
    p.add_argument("--resume", metavar="FILE",
                   help="continue the sweep recorded in FILE (a --results file): finished runs are not rerun")
    _budget_options(p)


def _network_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="paper", help="'paper' or a path to a scenario .toml (default paper)")
    p.add_argument("--row", type=int, help="the scenario's delay row from 0 (default 2, or a shorter grid's last)")
    p.add_argument("--seed", type=int, default=0, help="seed of noise, initial error and network (default 0)")
    p.add_argument("--precision", choices=["double", "float"], default="double",
                   help="the C's real type (default double)")
    p.add_argument("--duration", type=float, default=5.0, help="simulated seconds (default 5)")
    p.add_argument("--key", default=None, metavar="HEX", help="32 hex digits: tag every frame with SipHash-2-4")
    p.add_argument("--flip-rate", type=float, default=0.0, metavar="R", help="bit error rate of node -> master packets")
    p.add_argument("--keep", metavar="DIR", help="keep programs and logs in DIR")
    p.add_argument("--bench", metavar="FILE", nargs="?", const="BENCHMARKS.md", default=None,
                   help="measure wire sizes, master throughput, latency and CPU; write the network section "
                        "of FILE (default BENCHMARKS.md) instead of one compared run")
    _filter_options(p)
    _budget_options(p)


def _bench_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="BENCHMARKS.md", help="where to write the report (default BENCHMARKS.md)")
    p.add_argument("--repeat", type=int, default=5, help="repetitions for timed figures, median reported (default 5)")
    p.add_argument("--quick", action="store_true", help="skip the scaling sweeps and the Monte Carlo figures")


def _reproduce_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--runs", type=int, default=100, help="seeds per table (default 100)")
    p.add_argument("--out", default="reproduce", metavar="DIR",
                   help="tasks' results, experiment.json, experiment.md and figures (default ./reproduce)")
    p.add_argument("--doc", metavar="FILE", help="also write the document here, figures beside it (docs/experiment.md)")
    p.add_argument("--quick", action="store_true",
                   help="a subset: the motor's tables and figures, the filter comparison on two rows")
    p.add_argument("--quiet", action="store_true", help="no progress")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="N", help="local processes (default: all cores)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on an existing Dask distributed cluster (extra 'cluster')")


def parser() -> argparse.ArgumentParser:
    top = _Parser(prog="codegen", description=(
        "Turn a symbolic differentially flat robot model into verified embedded C for distributed "
        "derivative-free Kalman filtering under packet drops and variable delays."))
    top.add_argument("--version", action="version", version=f"dfeif-codegen {__version__}")
    sub = top.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    def add(name: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=COMMANDS[name], description=COMMANDS[name])
        _model_arg(p)
        return p

    _build_arguments(add("build"))
    _verify_arguments(add("verify"))
    _simulate_arguments(add("simulate"))
    p = add("scenario")
    p.add_argument("--out", metavar="FILE", help="write the scenario .toml here (default: print it)")
    p.add_argument("--shape", choices=["sinusoid", "seesaw", "circle", "figure8"], default="sinusoid",
                   help="how the flat outputs move together (default sinusoid: in phase)")
    p.add_argument("--amplitude", metavar="A[,A...]", help="per flat output (default: a tenth of its domain)")
    p.add_argument("--offset", metavar="C[,C...]", help="per flat output (default: its nominal value)")
    p.add_argument("--phase", metavar="RAD[,RAD...]", help="per flat output (default: from --shape)")
    p.add_argument("--period", type=float, default=None, metavar="S", help="seconds (default 5)")
    p.add_argument("--disturbance", metavar="KIND", default=None,
                   help="random_walk, gauss_markov, integrated_random_walk, integrated_gauss_markov or auto (the "
                        "most accurate whose loop holds, measured): add disturbance states, calibrated")
    p.add_argument("--tau", type=float, default=None, metavar="S", help="the (rate's) Gauss-Markov time constant [s]")
    p.add_argument("--param-error", default=None, metavar="SPREAD|NAME=REL,...",
                   help="calibrate against a plant with that model error (as simulate's), and write it")
    p.add_argument("--offsets", default=None, metavar="NAME[,NAME...]",
                   help="with --disturbance and --param-error: an [offsets] table for simulate --filters "
                        "offsets, estimating these parameters' offsets, its chains' q calibrated")
    p.add_argument("--scheduled", action="store_true", help="also q_scheduled, for simulate --filters scheduled")
    p.add_argument("--trajectory", metavar="FILE.csv",
                   help="track this CSV of the flat outputs (t, <output>, optionally <output>_d1, ...) instead of a shape")
    p.add_argument("--smoothing", type=float, default=0.0, metavar="S",
                   help="window [s] of the fit that differentiates outputs given without derivatives "
                        "(default: the fewest samples the fit needs)")
    _budget_options(p)

    p = add("inspect")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--ts", type=float, default=None, help="sampling period [s] (default: the model's)")
    _budget_options(p)

    _network_arguments(add("network"))
    _bench_arguments(add("bench"))
    _reproduce_arguments(sub.add_parser("reproduce", help=COMMANDS["reproduce"], description=COMMANDS["reproduce"]))
    return top


def _build_options(args: argparse.Namespace) -> dict:
    return dict(precision=args.precision, max_lag=args.max_lag, nodes=args.nodes, oosm=args.oosm or "replay",
                fusion=args.fusion or "difference", ts=args.ts, singular_rtol=args.singular_rtol,
                predictor=args.predictor, disturbance=args.disturbance, tau=args.tau, gate=args.gate)


def build(args: argparse.Namespace) -> int:
    """`codegen build`: the API's build, then what was written and the struct sizes; with
    `--check`, the API's check and the stale files on one line."""
    from dfeif_codegen.codegen import build

    if args.check:
        stale = build.check(args.model, args.out, **_build_options(args))
        if stale:
            raise StaleError(f"{args.out}: stale files for {args.model}: {', '.join(stale)} "
                             f"({build.rebuild_advice(args.model, args.out, **_build_options(args))})")
        print(f"codegen build --check: {args.out} is up to date for {args.model}")
        return 0
    module = build.build(args.model, args.out, **_build_options(args), force=args.force, **_budget(args))
    o = module.options
    print(f"codegen build: {module.name} -> {module.path}/ ({o.precision}, Ts {o.ts:g} s, NMAX {o.max_lag}, "
          f"{o.nodes} nodes, oosm {o.oosm}, fusion {o.fusion}, predictor {o.predictor}"
          + (f", disturbance {o.disturbance}" if o.disturbance else "") + (f", gate {o.gate:g}" if o.gate else "")
          + ")")
    width = max(len(f) for f in module.files)
    for fname in module.files:
        print(f"  {fname:<{width}}  {(module.path / fname).stat().st_size:>7} bytes")
    sizes = build.measure_sizes(module.path, module.name)
    if sizes is None:
        print("  sizeof: skipped (no working host C compiler: set CC)")
    else:
        print(f"  sizeof: node {sizes['node']} B, master {sizes['master']} B, packet {sizes['packet']} B "
              f"(host compiler)")
    if warning := o.stack_warning(module.n):
        print(f"codegen build: warning: {warning}", file=sys.stderr)
    return 0


def inspect(args: argparse.Namespace) -> int:
    from dfeif_codegen.symbolic import inspect_model

    info = inspect_model.inspect(args.model, ts=args.ts, **_budget(args))
    print(inspect_model.render_json(info) if args.json else inspect_model.render_text(info))
    return 0


def verify(args: argparse.Namespace) -> int:
    """`codegen verify`: the settings and scenario as they are known, the table, PASS or exit 1."""
    from dfeif_codegen.check import verify

    result = verify.verify(args.model, target=args.target, precision=args.precision, sanitize=args.sanitize,
                           scenario=args.scenario, inputs=args.inputs, max_lag=args.max_lag, nodes=args.nodes,
                           oosm=args.oosm or "replay", fusion=args.fusion or "difference",
                           predictor=args.predictor, gate=args.gate, progress=lambda line: print(line, flush=True),
                           **_budget(args))
    print(result.report())
    verify.check(result.errors)
    print("PASS")
    return 0


def simulate(args: argparse.Namespace) -> int:
    """`codegen simulate`: the tables (or the JSON with `--json -`); exit 1 when a run failed or diverged."""
    from dfeif_codegen import api

    result = api.simulate(
        args.model, scenario=args.scenario, runs=args.runs, seed=args.seed, nodes=args.nodes, max_lag=args.max_lag,
        oosm=args.oosm, fusion=args.fusion, reference=args.reference, filters=args.filters, plot=args.plot,
        json_path=args.json, quiet=args.quiet, engine=args.engine, workers=args.workers, scheduler=args.scheduler,
        results=args.results, csv=args.csv, resume=args.resume, param_error=args.param_error,
        predictor=args.predictor, **_budget(args))
    print(result.to_json() if args.json == "-" else result.report())
    if result.failures:  # a run that failed or diverged is a result to act on, not a footnote
        print(f"codegen simulate: {result.failure_line()}", file=sys.stderr)
        return 1
    return 0


def reproduce(args: argparse.Namespace) -> int:
    """`codegen reproduce`: what it ran and wrote; exit 1 when a run failed or diverged."""
    from dfeif_codegen.reproduction.run import reproduce as run

    result = run(args.runs, args.out, workers=args.workers, scheduler=args.scheduler, quick=args.quick, doc=args.doc,
                 quiet=args.quiet)
    print(result.report())
    return 1 if result.failures else 0


def bench(args: argparse.Namespace) -> int:
    from dfeif_codegen.check import bench

    bench.check_out(args.out, args.model)
    command = " ".join(["codegen", "bench", *map(shlex.quote, sys.argv[2:])]) if sys.argv[1:2] == ["bench"] else None
    result = bench.bench(args.model, repeat=args.repeat, command=command, quick=args.quick,
                         progress=lambda line: print(line, file=sys.stderr))
    out = Path(args.out)
    text = bench.keep_network_section(result.report(), out.read_text() if out.exists() else "")
    out.write_text(text)
    print(text)
    print(f"codegen bench: wrote {args.out}", file=sys.stderr)
    return 0


def scenario(args: argparse.Namespace) -> int:
    from dfeif_codegen.experiment import starter

    keys = ("out", "shape", "amplitude", "offset", "phase", "period", "disturbance", "tau", "param_error",
            "offsets", "scheduled", "trajectory", "smoothing")
    text = starter.scenario(args.model, **{k: getattr(args, k) for k in keys}, **_budget(args),
                            progress=lambda line: print(line, file=sys.stderr, flush=True))
    print(f"codegen scenario: wrote {args.out}" if args.out else text)
    return 0


def network(args: argparse.Namespace) -> int:
    """`codegen network`: one compared run (exit 1 on a mismatch), or with --bench the measurements."""
    from dfeif_codegen.check import harness, verify
    from dfeif_codegen.net import run

    if args.bench:
        from dfeif_codegen.net import bench

        harness.host_compiler()
        fig = bench.run_bench(Path(args.bench))
        print(bench.markdown(fig))
        print(f"codegen network: wrote the network section of {args.bench}", file=sys.stderr)
        return 0 if fig["network"]["equal"] else 1
    result = run.network(args.model, scenario=args.scenario, row=args.row, seed=args.seed,
                         precision=args.precision, oosm=args.oosm or "replay", fusion=args.fusion or "difference",
                         nodes=args.nodes, max_lag=args.max_lag, duration=args.duration, key=args.key,
                         flip_rate=args.flip_rate, keep=args.keep, predictor=args.predictor, **_budget(args))
    print(result.report())
    verify.check(result.errors)
    print("PASS")
    return 0


HANDLERS = {"build": build, "inspect": inspect, "verify": verify, "simulate": simulate, "bench": bench,
            "network": network, "scenario": scenario, "reproduce": reproduce}


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.command is None:
        parser().print_help()
        return 2
    try:
        return int(HANDLERS[args.command](args) or 0)
    except CodegenError as exc:
        print(f"codegen {args.command}: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt as exc:   # output.InterruptedAfterWrite says the build was written
        print(f"codegen {args.command}: interrupted{' ' + str(exc) if str(exc) else ''}", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
    except Exception as exc:  # a bug, not bad input: still one line, unless asked for the trace
        if os.environ.get("CODEGEN_DEBUG"):
            raise
        print(f"codegen {args.command}: internal error: {type(exc).__name__}: {exc} "
              "(CODEGEN_DEBUG=1 shows the traceback)", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
