"""The seeded network: camera -> node links (delays, drops) and node -> master links.

Everything is drawn up front from a numpy Generator, with the same number of uniforms whatever
the probabilities, so one seed gives one realization and runs that differ only in `p` or `d`
share their random numbers (paired comparisons between table rows).

Per item (a camera frame or a node packet): dropped with probability `p_drop`; otherwise late
with probability `p`, by a lag uniform on 1..d steps; otherwise on time. A lag is in whole
sampling periods: an item taken at step k with lag L arrives at step k + L, after that step's
on-time update. Items arriving at the same step come in a random (seeded) order.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

DROPPED = -1


@dataclass(frozen=True)
class Link:
    """Delay/drop law of one link: P(drop) = p_drop, P(late | not dropped) = p, lag ~ U{1..d}."""

    p: float = 0.0
    d: int = 0
    p_drop: float = 0.0

    def problem(self) -> str | None:
        """What is wrong with these numbers (for the scenario's one-line errors), or None."""
        if not 0.0 <= self.p <= 1.0:
            return f"delay probability p = {self.p} is not in [0, 1]"
        if not 0.0 <= self.p_drop < 1.0:
            return f"drop probability p_drop = {self.p_drop} is not in [0, 1)"
        if self.d < 0:
            return f"maximum delay d = {self.d} is negative"
        if self.p > 0 and self.d < 1:
            return f"delay probability p = {self.p} > 0 needs a maximum delay d >= 1"
        return None

    def draw(self, steps: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Lags (-1 dropped, 0 on time, >0 late) and a tie-break key in [0, 1) per item."""
        u = rng.random((4, steps))
        lag = np.where(u[1] < self.p, 1 + np.floor(u[2] * max(self.d, 1)).astype(int), 0)
        lag = np.where(u[0] < self.p_drop, DROPPED, lag)
        return lag, u[3]


class Network:
    """One realization for M nodes over `steps` steps.

    `lag[i, k]`: what happened to node i's camera frame of step k.
    `events`: (E, 3) the late frames arriving within the run as (arrival step, node, lag), by
    step, then node, then arrival order: the order the filters apply them (one array, not a
    Python loop per frame: a run draws thousands of them and takes milliseconds in C).
    `late[i][k]`: the same lags per node and arrival step, in arrival order.
    `source[i, k]`: the source step of node i's packet the master fuses at step k (-1: none) —
    the freshest packet arriving at k that is newer than the last one fused from that node.
    """

    def __init__(self, sensor: list[Link], uplink: list[Link], steps: int, rng: np.random.Generator):
        self.steps, self.nodes = steps, len(sensor)
        draws = [link.draw(steps, rng) for link in sensor]
        self.lag = np.array([lag for lag, _ in draws], dtype=int).reshape(self.nodes, steps)
        key = np.array([k for _, k in draws]).reshape(self.nodes, steps)
        node, src = np.nonzero(self.lag > 0)
        arrive = src + self.lag[node, src]
        keep = arrive < steps
        node, src, arrive = node[keep], src[keep], arrive[keep]
        order = np.lexsort((key[node, src], node, arrive))
        self.events = np.stack([arrive[order], node[order], (arrive - src)[order]], axis=1)
        self.up_lag = np.array([link.draw(steps, rng)[0] for link in uplink], dtype=int).reshape(self.nodes, steps)
        self.source = np.full((self.nodes, steps), -1, dtype=int)
        for i in range(self.nodes):
            best = np.full(steps, -1, dtype=int)
            ok = self.up_lag[i] >= 0
            src = np.nonzero(ok)[0]
            arrive = src + self.up_lag[i][src]
            keep = arrive < steps
            np.maximum.at(best, arrive[keep], src[keep])
            # fused at k when newer than every packet fused before (the running maximum)
            before = np.concatenate([[-1], np.maximum.accumulate(best)[:-1]])
            self.source[i] = np.where(best > before, best, -1)

    @cached_property
    def late(self) -> list[dict[int, list[int]]]:
        out: list[dict[int, list[int]]] = [{} for _ in range(self.nodes)]
        for k, i, lag in self.events.tolist():
            out[i].setdefault(k, []).append(lag)
        return out
