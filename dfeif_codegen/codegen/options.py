"""Typed build options: what the C bakes in as #defines, validated once before any work starts."""

from __future__ import annotations

import math
import shlex
from dataclasses import dataclass

from dfeif_codegen.constants import NODES_LIMIT
from dfeif_codegen.errors import CodegenError
from dfeif_codegen.symbolic.disturbance import (KINDS as DISTURBANCES, TAU_ONLY_TIMED, TIMED, Disturbance,
                                                 brunovsky_refusal)
from dfeif_codegen.symbolic.sampling import PREDICTORS, for_method

MAX_LAG_LIMIT = 4096
OOSM_METHODS = ("replay", "retrodict")
FUSION_RULES = ("difference", "paper", "ci")
PRECISIONS = ("double", "float")
# A replay node stores the P prior of every CHECK_EVERY-th step only (the P recursion of the
# canonical model reads neither x nor z, so the others are recomputed): 4 cuts the ring's P to a
# quarter (and packing halves it) for at most 3 extra P steps per late measurement.
CHECK_EVERY = 4
# `codegen build` warns when the replay's stack frame passes this: Cortex-M main stacks are
# typically 1-8 KiB (a CMSIS startup file's default is 1 KiB, an RTOS task's often less), and an
# overflow there corrupts memory silently, only on a late measurement's replay.
REPLAY_STACK_WARN = 8 * 1024


def _number(value: float) -> str:
    """A float option as short as it reads (`0.01`), but exact: `:g` alone keeps 6 digits, so a
    banner's --ts 0.0123456789 would regenerate a build at --ts 0.0123457."""
    text = f"{value:g}"
    return text if float(text) == value else repr(value)


class BuildError(CodegenError):
    """A bad build option or an output folder that cannot be written."""


@dataclass(frozen=True)
class Options:
    """Build options baked into the C as #defines."""

    ts: float
    max_lag: int = 32
    nodes: int = 2
    oosm: str = "replay"
    fusion: str = "difference"
    precision: str = "double"
    singular_rtol: float = 1e-6  # control returns ERR_SINGULAR below this fraction of |det G| nominal
    predictor: str | None = None  # u held, or (None) the default (held; brunovsky with retrodict)
    disturbance: str | None = None  # disturbance states per chain: one of symbolic/disturbance.KINDS
    tau: float | None = None        # the Gauss-Markov time constant [s]
    gate: float | None = None       # innovation gate [standard deviations]; None: every measurement is used

    def __post_init__(self) -> None:
        ts = self.ts
        if isinstance(ts, bool) or not isinstance(ts, (int, float)) or not math.isfinite(ts) or not 1e-9 <= ts <= 1e3:
            raise BuildError(f"--ts must be a sampling period in seconds in [1e-9, 1e3], got {ts!r}"
                             + (f" (a {type(ts).__name__})" if not isinstance(ts, (int, float)) else ""))
        rtol = self.singular_rtol
        if isinstance(rtol, bool) or not isinstance(rtol, (int, float)) or not 0 <= rtol < 1:
            raise BuildError(f"--singular-rtol must be a number in [0, 1), got {rtol!r}")
        object.__setattr__(self, "singular_rtol", float(rtol))
        gate = self.gate
        if gate is not None:
            if isinstance(gate, bool) or not isinstance(gate, (int, float)) or not math.isfinite(gate) or gate <= 0:
                raise BuildError(f"--gate must be a number of standard deviations > 0, got {gate!r}")
            object.__setattr__(self, "gate", float(gate))
        object.__setattr__(self, "ts", float(ts))
        object.__setattr__(self, "predictor", for_method(self.predictor, self.oosm))
        for name, limit in (("max_lag", MAX_LAG_LIMIT), ("nodes", NODES_LIMIT)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= limit:
                flag = "--" + name.replace("_", "-")
                raise BuildError(f"{flag} must be an integer between 1 and {limit}, got {value!r}")
        for name, allowed in (("oosm", OOSM_METHODS), ("fusion", FUSION_RULES), ("precision", PRECISIONS),
                              ("predictor", PREDICTORS)):
            if getattr(self, name) not in allowed:
                raise BuildError(f"--{name} must be one of {', '.join(allowed)}, got {getattr(self, name)!r}")
        if self.oosm == "retrodict" and self.predictor != "brunovsky":
            raise BuildError(f"--oosm retrodict needs --predictor brunovsky (Xia's retrodiction inverts the "
                             f"transition over the lag, ill-conditioned for the {self.predictor} predictor's); "
                             "use --oosm replay")
        self._check_disturbance()

    def _check_disturbance(self) -> None:
        kind, tau = self.disturbance, self.tau
        if kind is None:
            if tau is not None:
                raise BuildError(TAU_ONLY_TIMED)
            return
        if kind not in DISTURBANCES:
            raise BuildError(f"--disturbance must be one of {', '.join(DISTURBANCES)}, got {kind!r}")
        if self.predictor == "brunovsky":
            raise BuildError(f"--disturbance {brunovsky_refusal(self.oosm)}")
        if kind in TIMED:
            if isinstance(tau, bool) or not isinstance(tau, (int, float)) or not math.isfinite(tau) or tau <= 0:
                raise BuildError(f"--tau must be the {kind} time constant in seconds, > 0, got {tau!r}")
            object.__setattr__(self, "tau", float(tau))
        elif tau is not None:
            raise BuildError(TAU_ONLY_TIMED)

    @property
    def holds_u(self) -> bool:
        """The filters predict with the applied u held (held and scheduled predictors)."""
        return self.predictor != "brunovsky"

    @property
    def scheduled(self) -> bool:
        """The filters also take the master's broadcast flat outputs σ (after u)."""
        return self.predictor == "scheduled"

    def flags(self, model_ts: float) -> str:
        """The `codegen build` options that differ from the defaults (the model's Ts among
        them): what a file's banner tells a user to regenerate it with."""
        default, out = Options(ts=model_ts), []
        for name in ("precision", "max_lag", "nodes", "oosm", "fusion", "ts", "singular_rtol", "disturbance", "tau",
                     "gate"):
            value = getattr(self, name)
            if value is not None and value != getattr(default, name):
                out.append(f"--{name.replace('_', '-')} {_number(value) if isinstance(value, float) else value}")
        if self.predictor != for_method(None, self.oosm):
            out.append(f"--predictor {self.predictor}")
        return " ".join(out)

    def command(self, model_arg: str, model_ts: float, out: str | None = None) -> str:
        """`codegen build MODEL_ARG <flags> [--out OUT]`: the command that makes this build again
        (`model_arg`: a built-in's name or a model file as passed; quoted for a POSIX shell)."""
        words = ["codegen build", shlex.quote(model_arg), self.flags(model_ts)]
        if out is not None and str(out) != "generated":
            words.append(f"--out {shlex.quote(str(out))}")
        return " ".join(w for w in words if w)

    @property
    def check_every(self) -> int:
        """Steps between the node's stored P priors: a retrodiction restarts the P recursion at
        the late step, so it keeps every one, and so does the scheduled predictor, whose P
        recursion reads each step's σ (a checkpoint before the window would need σ the ring no
        longer holds)."""
        return CHECK_EVERY if self.oosm == "replay" and not self.scheduled else 1

    @property
    def checkpoints(self) -> int:
        """NODE_NCHECK: enough stored P priors to hold the one at or before the window's oldest step."""
        return (self.max_lag + self.check_every - 1) // self.check_every + 1

    def replay_stack(self, n: int) -> int:
        """Bytes of the local arrays of node_replay.c.j2's replay() for n filter states (0 with
        retrodict, whose locals do not grow with NMAX): the undo copies old_x[NMAX * NX] and
        old_P[NODE_NCHECK_REALS] and the carried prior[NX + NPP]. Why: they grow with --max-lag
        (147 KB of double at 4096 on the motor) on the stack of whoever feeds a late frame."""
        if self.oosm != "replay":
            return 0
        npp = n * (n + 1) // 2
        reals = self.max_lag * n + self.checkpoints * npp + n + npp
        return reals * (4 if self.precision == "float" else 8)

    def stack_warning(self, n: int) -> str:
        """One line when the replay's frame (replay_stack) passes REPLAY_STACK_WARN, else ""."""
        size = self.replay_stack(n)
        if size <= REPLAY_STACK_WARN:
            return ""
        return (f"the late-measurement replay keeps about {size} bytes on the stack of the caller of "
                f"node_update_delayed (--max-lag {self.max_lag}, {n} states, {self.precision}; over "
                f"{REPLAY_STACK_WARN // 1024} KiB, more than a typical Cortex-M main stack): give that task the "
                "stack, or lower --max-lag")

    def disturbance_states(self) -> Disturbance | None:
        """The disturbance model the constants are built for (its densities are runtime values,
        the trailing entries of q; the unit one here only shapes the model)."""
        return None if self.disturbance is None else Disturbance(self.disturbance, (1.0,), self.tau)
