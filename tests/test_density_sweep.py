"""scripts/density_sweep.py's variants: KIND:FACTOR[:TAU] built from a scenario's [disturbance],
its initial spread of the d's carried to every kind, and a malformed variant refused with what
is wrong."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from dfeif_codegen.symbolic.disturbance import Disturbance

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import density_sweep  # noqa: E402

# as `codegen scenario --disturbance integrated_gauss_markov --tau 0.3` writes it for two chains
IGM = Disturbance("integrated_gauss_markov", (3.68e7, 1.93e7), 0.3, (512.0, 371.0))


def test_a_variant_scales_the_densities_and_keeps_the_spread():
    assert density_sweep.variant(IGM, "integrated_gauss_markov:0.5", 2) == IGM.scaled(0.5)
    assert density_sweep.variant(IGM, "integrated_gauss_markov:2:1.5", 2) == Disturbance(
        "integrated_gauss_markov", (7.36e7, 3.86e7), 1.5, (512.0, 371.0))
    # a kind without a time constant drops the scenario's tau, keeps the d's spread
    assert density_sweep.variant(IGM, "random_walk:1", 2) == Disturbance("random_walk", IGM.q, None, (512.0, 371.0))


def test_a_d_then_rates_spread_gives_a_first_order_kind_the_ds():
    irw = Disturbance("integrated_random_walk", (4.0,), None, (1.0, 2.0, 3.0, 4.0))
    assert density_sweep.variant(irw, "random_walk:1", 2).p0_std == (1.0, 2.0)
    assert density_sweep.variant(irw, "integrated_random_walk:1", 2).p0_std == (1.0, 2.0, 3.0, 4.0)


@pytest.mark.parametrize("text, says", [
    ("brownian:1", "KIND one of"), ("random_walk", "KIND:FACTOR"), ("random_walk:x", "are numbers"),
    ("gauss_markov:1:a", "are numbers")])
def test_a_malformed_variant_says_what_is_wrong(text, says):
    with pytest.raises(ValueError, match=says):
        density_sweep.variant(IGM, text, 2)


def test_a_timed_kind_without_a_tau_anywhere_is_refused():
    rw = Disturbance("random_walk", (1.0,))
    with pytest.raises(ValueError, match="gauss_markov needs a time constant: gauss_markov:1:TAU"):
        density_sweep.variant(rw, "gauss_markov:1", 1)
