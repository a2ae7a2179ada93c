"""scripts/step_cost.py: a node step's instructions split between the generated code and the shared
objects it calls (the explanation BENCHMARKS.md's node predict + update row needs)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from conftest import require_tool

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import step_cost  # noqa: E402

# A callgrind dump written by hand in the format's compressed form: main (program) costs 5 + 2,
# calls foo (libm) whose call line carries foo's inclusive 40 (not main's own), foo costs 30 + 10.
DUMP = """version: 1
creator: callgrind-3.19.0
events: Ir
ob=(1) /tmp/prog
fl=(1) prog.c
fn=(1) main
10 5
cob=(2) /usr/lib/libm.so.6
cfi=(2) s_sin.c
cfn=(2) sin
calls=1 20
+1 40
+1 2
ob=(2)
fl=(2)
fn=(2)
20 30
+3 10
totals: 47
"""


def test_self_cost_per_object_of_a_written_dump():
    assert step_cost.self_cost_by_object(DUMP) == {"/tmp/prog": 7, "/usr/lib/libm.so.6": 40}


def test_node_step_split_adds_up_to_callgrinds_totals(host_cc, tmp_path):
    """On a real run the self costs over all objects are callgrind's own total of the section (an
    independent count); the held predictor's mean calls the C library (the motor's sin and cos), the
    Brunovsky predictor, linear in the state, and the update call nothing outside the program."""
    require_tool("valgrind", "valgrind")
    held = step_cost.measure("dc_motor_link", "held", tmp_path / "held")
    for dump in (tmp_path / "held" / "cg").glob("callgrind.out*"):
        text = dump.read_text()
        total = re.search(r"^(?:summary|totals): (\d+)", text, re.M)
        if total:
            assert sum(step_cost.self_cost_by_object(text).values()) == int(total.group(1)), dump.name
    assert sum(held["node_predict"]["of which"].values()) > 0   # libm's, whatever its file name
    assert held["node_update"]["of which"] == {}
    brunovsky = step_cost.measure("dc_motor_link", "brunovsky", tmp_path / "brunovsky")
    assert brunovsky["node_predict"]["of which"] == {}
