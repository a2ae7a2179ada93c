"""The filter, fusion and control math as CasADi SX functions: the kernel set of one build.

Why CasADi: it turns the symbolic model into straight-line C with shared subexpressions and the
known structure folded away (Brunovsky A_d is constant and sparse, C = e_head picks entries), so
no generic matrix code ships to the microcontroller. Every kernel is one step of work; loops over
the late-measurement window, over nodes and over the CI iterations are plain C in the templates.

The package, dependencies pointing down the list:
  linalg    symbolic linear algebra on small SX matrices (Cholesky, inverses, packed storage)
  chains    the model's chain structure: A, B, C, A_d(t), Q_d(t), angle wrap, gain, posterior
  csource   CasADi's C text post-processed into typed, styled C (`c_source`, `packed_wrapper`)
  node      the node filter's kernels (predict, update, node_predict, info)
  retro     the node's retrodiction kernels (`--oosm retrodict`)
  loops     node_predict and info of long chains as C loops over small parts
  fusion_loops  the master's fusion kernels of long chains as C loop nests
  fusion    the master's kernels (difference and paper rules, stale-packet prediction)
  held      the held-input predictor's kernels (`--predictor held`, the default)
  ci        covariance intersection's Newton-step kernels (`--fusion ci`)
  control   the flatness-based control kernel
and this module, which picks the kernels the options need (`build`): a new kernel is written in
its concept's module and listed here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca

from dfeif_codegen.codegen.kernels import ci, control, fusion, fusion_loops, held, loops, node, retro
from dfeif_codegen.codegen.kernels.chains import Chains
from dfeif_codegen.codegen.kernels.csource import Loop
from dfeif_codegen.codegen.options import Options

# Kernels whose work array is a local of the kernel, not a parameter: then no store into it can
# alias an argument, and the compiler keeps the intermediates in registers (the node's kernels,
# called once per step on the hot path; measured: about half their instructions; and info, whose
# Cortex-M4F code this halves at n = 10; and domain and noise, called at init only, so that
# their callers need no work array).
LOCAL_WORK = ("update", "node_predict", "node_predict_P", "retro_step", "retro_finish", "info", "domain", "noise")

# node_predict and info are printed as loops (`Loop`) when their straight-line code would have
# more operations (CasADi's count) than their limit here. The limits differ because what the
# loops cost does (chains of n integrators, docs/algorithms.md "Looped kernels"): node_predict
# runs every step and every replayed step, and its loops take about twice the straight line's
# instructions (looped from 500 operations, n = 7, the node step jumped 2.8x from n = 6); info runs
# once per packet and its loops save the most bytes (its straight-line code grows as n^2.5). With
# node_predict straight-line up to 2,500 operations (a chain of 12 has 2,288) and info looped above
# 500 (n >= 7: 601; two_link_arm 410), the node step grows at most 1.6x per n over n = 2..12 and
# the filter kernels' .text as n^1.85.
# The master's kernels (kernels.fusion_loops) are loops around written-out sums, O(n^2) code, about
# a third more host instructions than the straight-line code (master_fuse, 2 packets: 12,795 ->
# 17,753 at n = 7, 28,924 -> 37,887 at n = 10) and fewer bytes from n = 6 (Cortex-M4F: 24% fewer
# at n = 7, 56% at n = 10). Looped from n = 7 as info is (master_gain 1,155 operations there,
# fuse_finish 1,975 / 604 for the difference / paper rule, master_info 583; at n = 6 786, 1,290,
# 413, 398; the difference rule's finish works in the prior's factor, fusion.fuse_finish_difference), and so advance (Brunovsky builds: 629 at n = 7, 431 at n = 6, pvtol 458): their .text grows
# as n^1.97 over n = 2..12 (n^1.87 with advance; straight-line n^2.6), the built-in models but
# pvtol's master_gain, master_info and fuse_finish (n = 8) stay straight-line.
# The held predictor's node_predict and node_predict_P (the default build's) are loops when the
# covariance step alone (held.covariance_ops: the mean is printed straight-line either way) has
# more operations than "held_covariance": held.node_predict_loop, 1.15-1.26x the straight line's
# instructions (n = 6..12), O(n^2) code. Chains of n: 908 operations at n = 9, 1,219 at 10
# (with Q0 an argument, `held.noise`: 951 and 1,272 when it was summed from q each step);
# two_link_arm 474, 897 with Gauss-Markov states, pvtol 638 with them: straight-line; the
# arm's integrated kinds (1,437 and 1,459: two states per chain) looped. Looped from n = 10, the node step
# (update + node_predict) grows at most 1.53x per n over n = 2..12 (1.38x from n = 9 to 10; 1.51x
# on the Cortex-M4F), the filter kernels' .text as n^1.75 (straight-line n^2.03: 19,344 B at
# n = 12, now 10,452). Looped from n = 9 the Cortex-M4F's node step jumped 1.59x, from n = 8
# the host's 1.60x: too close to the limit.
LOOP_OPS = {"node_predict": 2500, "info": 500, "master_gain": 1000, "fuse_finish_difference": 1500,
            "master_info": 500, "fuse_finish": 500, "advance": 500, "held_covariance": 1200}


@dataclass
class KernelSet:
    """The CasADi functions of one model, grouped by the C file they go into."""

    groups: dict[str, list[ca.Function]] = field(default_factory=dict)
    local_work: set[str] = field(default_factory=set)   # groups whose kernels keep work locally
    own_work: set[str] = field(default_factory=set)     # kernels with a local work array
    # kernel -> the kernel it calls on packed copies of its n x n arguments (`packed_wrapper`)
    wrappers: dict[str, str] = field(default_factory=dict)
    # kernel -> the C loops that compute it instead of its straight-line code (`Loop`)
    loops: dict[str, Loop] = field(default_factory=dict)

    def all(self) -> list[ca.Function]:
        return [f for fs in self.groups.values() for f in fs]


def build(flat, opts: Options, prefix: str) -> KernelSet:
    """All kernels the chosen options need, named `<prefix>_kern_<name>`."""
    s = Chains(flat, opts)
    name = lambda k: f"{prefix}_kern_{k}"  # noqa: E731
    info = node.info(s, name("info"))
    h = None if opts.predictor == "brunovsky" else \
        held.Held(flat, opts.ts, opts.disturbance_states(), scheduled=opts.predictor == "scheduled")
    if h is not None:
        node_predict = held.node_predict(h, name("node_predict"))
        filt = [held.predict(h, name("predict")), node_predict, node.update(s, name("update")), info]
        filt += [held.node_predict_P(h, name("node_predict_P"))] if opts.oosm == "replay" and opts.check_every > 1 else []
        filt += [held.domain(h, name("domain")), held.noise(h, name("noise"))]
    else:
        node_predict = node.node_predict(s, name("node_predict"))
        filt = [node.predict(s, name("predict")), node_predict, node.update(s, name("update")), info]
    if opts.oosm == "retrodict":
        filt += [retro.retro_step(s, name("retro_step")), retro.retro_finish(s, name("retro_finish"))]
    if opts.fusion == "difference":
        fus = [fusion.master_gain(s, name("master_gain")), fusion.fuse_finish_difference(s, name("fuse_finish"))]
        fused = ["master_gain", "fuse_finish_difference"]
    else:
        fus = [fusion.master_info(s, name("master_info")), fusion.fuse_finish(s, name("fuse_finish"))]
        fused = ["master_info", "fuse_finish"]
    if opts.fusion == "ci":
        fus += ci.ci_kernels(s, name)
    if h is None:   # the held and scheduled masters predict stale packets step by step
        fus += [fusion.advance(s, name("advance")), fusion.input_step(s, name("input_step"))]
    # the master's predict is the node's on packed copies: the same expressions (bit for bit),
    # so its Theta(n^3) straight-line code is not printed twice (nor its loops: it calls them)
    loopable = [("info", info, loops.info_loop)]
    if h is None:
        loopable.append(("node_predict", node_predict, loops.node_predict_loop))
    loopable += [(key, f, lambda s, _, key=key, f=f: fusion_loops.loop_of(key, f)) for key, f in zip(fused, fus)]
    loopable += [("advance", f, lambda s, _, f=f: fusion_loops.advance_loop(s, f)) for f in fus[2:]
                 if f.name() == name("advance")]
    looped = {f.name(): loop(s, f.name()) for key, f, loop in loopable if f.n_instructions() > LOOP_OPS[key]}
    if h is not None and not h.scheduled and held.covariance_ops(h) > LOOP_OPS["held_covariance"]:
        looped[name("node_predict")] = held.node_predict_loop(h, name("node_predict"))
        if opts.oosm == "replay":   # the replay's covariance steps: the same loops, node_predict's parts
            looped[name("node_predict_P")] = held.node_predict_P_loop(h, name("node_predict"))
    return KernelSet({"filter": filt, "fusion": fus, "control": [control.control(s, name("control"), h and h.law)]},
                     local_work={"fusion"}, own_work={name(k) for k in LOCAL_WORK},
                     wrappers={name("predict"): name("node_predict")}, loops=looped)
