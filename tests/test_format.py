"""The layout of the generated C: every line at most 100 columns, and clang-format with the
shipped style file (templates/.clang-format) changes nothing, for the built-in models in several
option sets and for user models with names of MODEL_NAME_LIMIT characters, the longest the model
loader accepts (the name prefixes every identifier; a longer one is refused at load time).
The generator lays the code out itself (codegen/layout.py), so these tests are what ties its
output to the style file."""

from __future__ import annotations

import subprocess
from importlib import resources
from pathlib import Path

import pytest

from conftest import require_tool
from dfeif_codegen.check import bench_peers
from dfeif_codegen.codegen import build, layout
from dfeif_codegen.symbolic.model import MODEL_NAME_LIMIT
from test_user_models import FLEX_JOINT, LONG_CHAIN, MIXED

VARIANTS = [
    ("dc_motor_link", {}),
    ("dc_motor_link", {"precision": "float", "oosm": "retrodict", "fusion": "ci", "nodes": 3}),
    ("dc_motor_link", {"fusion": "paper", "max_lag": 5}),
    ("two_link_arm", {}),
    ("two_link_arm", {"precision": "float", "oosm": "retrodict", "fusion": "paper"}),
    ("two_link_arm", {"fusion": "ci", "nodes": 4}),
    ("user:flex_joint_link_a", {"oosm": "retrodict", "fusion": "ci"}),
    ("user:mixed_two_input_m", {"precision": "float"}),
    ("user:long_chain_sevens", {"precision": "float"}),   # kernels printed as loops
    ("pvtol", {"precision": "float"}),                     # a dynamic extension: extension_step
    ("chain:10", {"precision": "float"}),                  # fusion kernels printed as loops
]
STYLE = Path(str(resources.files("dfeif_codegen.templates") / ".clang-format"))


def _spec(name: str, tmp: Path):
    """A built-in name, a synthetic chain of n integrators (`chain:n`), or a user model (from
    test_user_models) renamed to a long name."""
    if name.startswith("chain:"):
        path = tmp / f"chain{name[6:]}.toml"
        path.write_text(bench_peers.chain_model(int(name[6:])))
        return str(path)
    if not name.startswith("user:"):
        return name
    new = name[5:]
    assert len(new) == MODEL_NAME_LIMIT
    text, old = {"flex": (FLEX_JOINT, "flex_joint"), "mixe": (MIXED, "mixed"),
                 "long": (LONG_CHAIN, "long_chain")}[new[:4]]
    path = tmp / f"{new}.toml"
    path.write_text(text.replace(f'name = "{old}"', f'name = "{new}"', 1))
    return str(path)


@pytest.fixture(scope="module")
def modules(tmp_path_factory):
    root = tmp_path_factory.mktemp("format")
    return [build.build(_spec(name, root), root / str(i), **opts).path for i, (name, opts) in enumerate(VARIANTS)]


def test_no_line_over_100_columns(modules):
    for folder in modules:
        for path in sorted(folder.iterdir()):
            if path.name == "manifest.json":   # data (file hashes), not code
                continue
            for number, line in enumerate(path.read_text().splitlines(), 1):
                assert len(line) <= layout.LIMIT, f"{path.name}:{number}: {len(line)} columns"


def test_clang_format_changes_nothing(modules):
    clang_format = require_tool("clang-format", "clang-format")
    assert STYLE.is_file(), "the style file ships with the templates"
    for folder in modules:
        for path in sorted(folder.glob("*.[ch]")):
            out = subprocess.run([clang_format, f"--style=file:{STYLE}", str(path)], capture_output=True,
                                 text=True, timeout=120, check=True).stdout
            if out != path.read_text():
                diff = subprocess.run(["diff", str(path), "-"], input=out, capture_output=True, text=True).stdout
                pytest.fail(f"clang-format would change {folder.name}/{path.name}:\n{diff[:3000]}")


def test_pack_fits_or_aligns_after_the_parenthesis():
    head = "int function_with_a_long_name("
    params = [f"const double argument_{i}[{i + 1}]" for i in range(8)]
    one = layout.pack(head, params[:2], ");")
    assert one == head + params[0] + ", " + params[1] + ");"
    wrapped = layout.pack(head, params, ");").splitlines()
    assert len(wrapped) > 1 and all(len(line) <= layout.LIMIT for line in wrapped)
    assert all(line.startswith(" " * len(head)) for line in wrapped[1:])
    assert " ".join(line.strip() for line in wrapped) == head + ", ".join(params) + ");"
    # greedy: no line could take the next line's first parameter
    for line, nxt in zip(wrapped, wrapped[1:]):
        assert len(line) + 1 + len(nxt.strip().split(", ")[0]) + 1 > layout.LIMIT


def test_pack_splits_a_declaration_too_long_for_its_line_as_clang_format_does(tmp_path):
    """A parameter that does not fit even alone at the alignment column is broken between its
    type and its declarator (indented 4 more), and the next parameter starts a new line; the
    oracle is clang-format with the shipped style, which must leave the result unchanged."""
    clang_format = require_tool("clang-format", "clang-format")
    head = "int a_model_name_of_17_kern_retro_step("
    params = ["const a_model_name_of_17_real n[1]", "a_model_name_of_17_real w[A_MODEL_NAME_OF_17_KERN_RETRO_STEP_SZ_W]",
              "const a_model_name_of_17_real Tp[9]", "int a"]
    for order in (params, params[:1] + params[2:] + params[1:2]):
        text = layout.pack(head, order, ");")
        lines = text.splitlines()
        assert all(len(line) <= layout.LIMIT for line in lines) and len(lines) >= 3
        assert any(line == " " * len(head) + "a_model_name_of_17_real" for line in lines), text
        path = tmp_path / "p.h"
        path.write_text(text + "\n")
        out = subprocess.run([clang_format, f"--style=file:{STYLE}", str(path)], capture_output=True,
                             text=True, timeout=60, check=True).stdout
        assert out == text + "\n", out


def test_lay_out_joins_what_fits_and_repacks_conditions():
    text = "    rc = call(a,\n              b);\n    if (first_condition_that_is_long(x) || second_condition_that_is_long(y) ||\n" \
           "        third_condition_that_is_longer_still(z) || fourth(w)) {\n"
    out = layout.lay_out(text).splitlines()
    assert out[0] == "    rc = call(a, b);"
    assert out[1].startswith("    if (first_condition_that_is_long(x) ||") and out[1].endswith("||")
    assert all(len(line) <= layout.LIMIT for line in out)
    assert out[-1].endswith("fourth(w)) {") and out[-1].startswith(" " * 8)
    # comments, preprocessor lines and string contents are left alone
    keep = '/* a (comment\n * over lines */\n#define X (1 +\\\n  2)\n    printf("(%d", k);\n'
    assert layout.lay_out(keep) == keep


def test_header_macros_carry_the_prefix(modules):
    """Every macro a header defines is <P>_...: headers of several models can be included together
    (the .c files' own short macros such as NX stay inside their file)."""
    import re

    for folder in modules:
        upper = folder.name.upper()
        for path in sorted(folder.glob("*.h")):
            names = re.findall(r"(?m)^#define (\w+)", path.read_text())
            assert names and all(n.startswith(upper + "_") for n in names), (path.name, names)
