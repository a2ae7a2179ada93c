"""bench_report's struct-size table names the generated structs by the model's C prefix."""

from __future__ import annotations

import shutil
from pathlib import Path

from dfeif_codegen.check import bench_report

DATA = Path(__file__).parent / "data"


def test_struct_table_names_a_model_files_structs_by_its_model_name(tmp_path):
    """`codegen bench free_cart_v2.toml` benches model `free_cart`: its structs are free_cart_node,
    ..., not `free_cart_v2.toml_node` (the argument) nor the file's stem."""
    spec = tmp_path / "free_cart_v2.toml"
    shutil.copy(DATA / "free_cart.toml", spec)
    sizes = {"node": 100, "master": 50, "packet": 20}
    rows = bench_report.struct_table(str(spec), sizes, {k: 2 * v for k, v in sizes.items()})
    assert rows[3:6] == ["| `free_cart_node` | 100 | 200 | 2.00 |", "| `free_cart_master` | 50 | 100 | 2.00 |",
                         "| `free_cart_packet` | 20 | 40 | 2.00 |"]


def test_struct_table_keeps_a_builtin_models_name():
    assert bench_report.struct_table("dc_motor_link", {"node": 1, "master": 1, "packet": 1},
                                     {"node": 2, "master": 2, "packet": 2})[3].startswith("| `dc_motor_link_node` |")
