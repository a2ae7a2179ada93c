"""cppcheck --addon=misra over the generated library: no finding of any rule the addon checks in
the files listed in OWNED (code the templates write), none in the CasADi kernel bodies, and
docs/misra.md lists, per module, every rule that is found and where.

Without the rule texts (sold by MISRA) cppcheck reports rule numbers only; that is enough for
these checks. A finding fails here with its file, line and source text.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import require_tool
from dfeif_codegen.check import misra
from dfeif_codegen.codegen import build
from test_user_models import LONG_CHAIN, MIXED

ROOT = Path(__file__).resolve().parents[1]
# Files (by what follows the model name) that must have no finding at all.
OWNED = (".h", "_internal.h", "_kernels.h", "_node.c", "_master.c", "_wire.c", "_control.c")
# The documented built-in variants, and a user MIMO model (two inputs, one flat output an angle).
VARIANTS = {**misra.VARIANTS, "user model mixed (2 inputs), float, ci": ("user:mixed", {"precision": "float",
                                                                                         "fusion": "ci"}),
            "user model long_chain (7 states: looped kernels)": ("user:long_chain", {}),
            # the innovation gate's code paths: on time and replay, on time and retrodiction
            "dc_motor_link, gate": ("dc_motor_link", {"gate": 3.0}),
            "dc_motor_link, float, retrodict, gate": ("dc_motor_link", {"precision": "float", "oosm": "retrodict",
                                                                         "gate": 3.0})}


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    require_tool("cppcheck", "cppcheck")
    root = tmp_path_factory.mktemp("misra")
    (root / "mixed.toml").write_text(MIXED)
    (root / "long_chain.toml").write_text(LONG_CHAIN)
    out = {}
    for i, (label, (name, opts)) in enumerate(VARIANTS.items()):
        spec = str(root / f"{name[5:]}.toml") if name.startswith("user:") else name
        mod = build.build(spec, root / str(i), **opts)
        out[label] = (mod, misra.findings(mod.path, mod.name))
    return out


def _owned(mod, file: str) -> bool:
    return file.startswith(mod.name) and file[len(mod.name):] in OWNED


def test_owned_files_exist(found):
    """Every OWNED file is in each module (a renamed file must not pass the test unseen)."""
    for label, (mod, fs) in found.items():
        for suffix in OWNED:
            assert (mod.path / (mod.name + suffix)).is_file(), (label, suffix)


def test_no_finding_in_owned_template_code(found):
    for label, (mod, fs) in found.items():
        bad = [f for f in fs if _owned(mod, f.file)]
        lines = [f"{f.file}:{f.line}: rule {f.rule}: "
                 + (mod.path / f.file).read_text().splitlines()[f.line - 1].strip() for f in bad]
        assert not bad, f"{label}: MISRA findings\n" + "\n".join(lines)


def test_no_findings_in_kernel_bodies(found):
    for label, (mod, fs) in found.items():
        assert not [f for f in fs if f.kernel and f.rule not in misra.KERNEL_FINDINGS], label


def test_docs_list_every_rule_found(found):
    text = (ROOT / "docs" / "misra.md").read_text()
    for label, (mod, fs) in found.items():
        if label not in misra.VARIANTS:
            continue
        section = text.split(f"## {label}\n", 1)[1].split("\n## ", 1)[0]
        rules = {f.rule for f in fs}
        assert {row.split(" | ")[0][2:] for row in section.splitlines() if row.startswith("| ") and
                row[2].isdigit()} == rules, label


@pytest.mark.parametrize("suffix,probe,rule", [
    ("_wire.c", "\nint dc_motor_link_probe(const real* a, real* b);\n"
                "int dc_motor_link_probe(const real* a, real* b)\n{\n    memcpy(b, a, sizeof(real));\n"
                "    return 0;\n}\n", "17.7"),
    ("_internal.h", "\nstatic inline int dc_motor_link_probe(int a)\n{\n    if (a > 0) {\n        return 1;\n"
                    "    }\n    return 0;\n}\n", "15.5"),
])
def test_a_finding_in_an_owned_file_is_caught(tmp_path, suffix, probe, rule):
    """The check is live, in a source and in a header: an ignored memcpy result (rule 17.7), an
    early return (15.5) added to an owned file are reported there."""
    require_tool("cppcheck", "cppcheck")
    mod = build.build("dc_motor_link", tmp_path)
    path = mod.path / (mod.name + suffix)
    text = path.read_text()
    at = text.rindex("#endif") if suffix.endswith(".h") else len(text)
    path.write_text(text[:at] + probe + text[at:])
    assert any(f.rule == rule and f.file == path.name for f in misra.findings(mod.path, mod.name))


def test_help_prints_usage_and_writes_no_file(tmp_path, monkeypatch, capsys):
    """`python -m dfeif_codegen.check.misra --help` once wrote the report to a file named
    `--help`: the one argument is the report's path, an option is not."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as done:
        misra.main(["--help"])
    assert done.value.code == 0 and "usage:" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []
