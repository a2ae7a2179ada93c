"""`codegen`: the command line. Each subcommand lives in its own module; this file only parses
arguments and turns user errors into one line and a distinct exit code."""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from dfeif_codegen import __version__
from dfeif_codegen.errors import CodegenError

DEFAULT_MODEL = "dc_motor_link"

# subcommand -> (module, one-line help)
COMMANDS = {
    "build": ("dfeif_codegen.cli", "generate the C module for a model into generated/<model>"),
    "verify": ("dfeif_codegen.check.verify", "compile the generated C and compare it with the Python reference"),
    "simulate": ("dfeif_codegen.experiment.simulate", "run the closed-loop experiment (chapter tables, plots, JSON)"),
    "scenario": ("dfeif_codegen.experiment.starter", "write a starting scenario for a model (q, P0, poles, noise)"),
    "inspect": ("dfeif_codegen.symbolic.inspect_model", "show the derived flatness transform and discrete model"),
    "bench": ("dfeif_codegen.check.bench", "measure build time, code size, stack and instruction counts"),
}


def _model_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", nargs="?", default=DEFAULT_MODEL,
                   help=f"built-in model name or path to a .toml model file (default {DEFAULT_MODEL})")


def parser() -> argparse.ArgumentParser:
    top = argparse.ArgumentParser(prog="codegen", description=(
        "Turn a symbolic differentially flat robot model into verified embedded C for distributed "
        "derivative-free Kalman filtering under packet drops and variable delays."))
    top.add_argument("--version", action="version", version=f"dfeif-codegen {__version__}")
    sub = top.add_subparsers(dest="command", metavar="COMMAND")

    def add(name: str) -> argparse.ArgumentParser:
        p = sub.add_parser(name, help=COMMANDS[name][1], description=COMMANDS[name][1])
        _model_arg(p)
        return p

    def filter_options(p: argparse.ArgumentParser, many: bool = False) -> None:
        p.add_argument("--max-lag", type=int, default=32, metavar="N", help="late-measurement window (default 32)")
        p.add_argument("--nodes", type=int, default=None if many else 2, metavar="M",
                       help="camera nodes (default: " + ("the scenario's)" if many else "2)"))
        kind = dict(action="append") if many else dict(default=None)
        p.add_argument("--oosm", choices=["retrodict", "replay"], **kind,
                       help="late-measurement method" + (" (repeatable)" if many else " (default replay)"))
        p.add_argument("--fusion", choices=["paper", "difference", "ci"], **kind,
                       help="master fusion rule" + (" (repeatable)" if many else " (default difference)"))

    p = add("build")
    p.add_argument("--out", default="generated", help="output folder (default generated)")
    p.add_argument("--precision", choices=["double", "float"], default="double")
    filter_options(p)
    p.add_argument("--ts", type=float, default=None, help="sampling period [s] (default: the model's)")

    p = add("verify")
    p.add_argument("--target", choices=["host", "cortex-m4f"], default="host")
    p.add_argument("--precision", choices=["double", "float"], default=None,
                   help="default: double on the host, float on cortex-m4f")
    p.add_argument("--sanitize", action="store_true", help="host: build with -fsanitize=address,undefined")
    p.add_argument("--scenario", default="paper",
                   help="'paper' or a scenario .toml to record (its first row with late frames)")
    p.add_argument("--inputs", choices=["recorded", "own"], default="recorded",
                   help="the filters predict with the recorded inputs v, which the recorded measurements "
                        "reflect (default), or with the v the C controller computes")
    filter_options(p)

    p = add("simulate")
    p.add_argument("--scenario", default="paper", help="'paper' or a path to a scenario .toml")
    p.add_argument("--runs", type=int, default=None, help="seeds to average over")
    p.add_argument("--seed", type=int, default=0, help="first seed")
    filter_options(p, many=True)
    p.add_argument("--reference", choices=["sinusoid", "seesaw"], action="append", help="(repeatable)")
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--json", metavar="FILE", help="write every figure machine-readably ('-' for stdout)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")

    p = add("scenario")
    p.add_argument("--out", metavar="FILE", help="write the scenario .toml here (default: print it)")

    p = add("inspect")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--ts", type=float, default=None, help="sampling period [s] (default: the model's)")

    p = add("bench")
    p.add_argument("--out", default="BENCHMARKS.md", help="where to write the report")
    p.add_argument("--repeat", type=int, default=5, help="repetitions for timed figures (median reported)")
    return top


def run(args: argparse.Namespace) -> int:
    """`codegen build`: the API's build, then what was written and the struct sizes."""
    from dfeif_codegen.codegen import build

    module = build.build(args.model, args.out, precision=args.precision, max_lag=args.max_lag,
                         nodes=args.nodes, oosm=args.oosm or "replay", fusion=args.fusion or "difference",
                         ts=args.ts)
    o = module.options
    print(f"codegen build: {module.name} -> {module.path}/ ({o.precision}, Ts {o.ts:g} s, NMAX {o.max_lag}, "
          f"{o.nodes} nodes, oosm {o.oosm}, fusion {o.fusion})")
    width = max(len(f) for f in module.files)
    for fname in module.files:
        print(f"  {fname:<{width}}  {(module.path / fname).stat().st_size:>7} bytes")
    sizes = build.measure_sizes(module.path, module.name)
    if sizes is None:
        print("  sizeof: skipped (no working host C compiler: set CC)")
    else:
        print(f"  sizeof: node {sizes['node']} B, master {sizes['master']} B, packet {sizes['packet']} B "
              f"(host compiler)")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    if args.command is None:
        parser().print_help()
        return 2
    try:
        module = importlib.import_module(COMMANDS[args.command][0])
        return int(module.run(args) or 0)
    except CodegenError as exc:
        print(f"codegen {args.command}: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print(f"codegen {args.command}: interrupted", file=sys.stderr)
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
