"""cppcheck --addon=misra over the generated library: every rule it reports in the code the
templates write is an explained advisory deviation or a documented tool report, nothing is
found in the CasADi kernel bodies, and docs/misra.md lists every rule that is found.

Without the rule texts (sold by MISRA) cppcheck reports rule numbers only; that is enough for
these checks. A new finding of any other rule fails here with its file, line and source text.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import require_tool
from dfeif_codegen.check import misra
from dfeif_codegen.codegen import build

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    require_tool("cppcheck", "cppcheck")
    root = tmp_path_factory.mktemp("misra")
    out = {}
    for i, (label, (name, opts)) in enumerate(misra.VARIANTS.items()):
        mod = build.build(name, root / str(i), **opts)
        out[label] = (mod, misra.findings(mod.path, mod.name))
    return out


def test_only_explained_rules_in_template_code(found):
    explained = set(misra.DEVIATIONS) | set(misra.NOT_VIOLATIONS)
    for label, (mod, fs) in found.items():
        bad = [f for f in fs if not f.kernel and f.rule not in explained]
        lines = [f"{f.file}:{f.line}: rule {f.rule}: "
                 + (mod.path / f.file).read_text().splitlines()[f.line - 1].strip() for f in bad]
        assert not bad, f"{label}: unexplained MISRA findings\n" + "\n".join(lines)


def test_no_findings_in_kernel_bodies(found):
    for label, (mod, fs) in found.items():
        assert not [f for f in fs if f.kernel and f.rule not in misra.KERNEL_FINDINGS], label


def test_dead_code_reports_only_for_one_output_models(found):
    """Rule 2.2 is reported for multiplications by NY = 1, so never for two_link_arm (NY = 2)."""
    for label, (mod, fs) in found.items():
        if mod.name == "two_link_arm":
            assert not [f for f in fs if f.rule == "2.2"], label
    assert any(f.rule == "2.2" for mod, fs in found.values() if mod.name == "dc_motor_link" for f in fs)


def test_docs_list_every_rule_found(found):
    text = (ROOT / "docs" / "misra.md").read_text()
    for label, (mod, fs) in found.items():
        assert f"## {label}" in text
        for rule in {f.rule for f in fs}:
            assert f"| {rule} |" in text and f"**{rule}**" in text, (label, rule)


def test_a_required_rule_is_caught(tmp_path):
    """The check is live: an ignored memcpy result (rule 17.7) added to a module is reported."""
    require_tool("cppcheck", "cppcheck")
    mod = build.build("dc_motor_link", tmp_path)
    node = mod.path / "dc_motor_link_node.c"
    node.write_text(node.read_text() + "\nvoid dc_motor_link_probe(real* a, const real* b);\n"
                    "void dc_motor_link_probe(real* a, const real* b)\n{\n    memcpy(a, b, sizeof(real));\n}\n")
    assert any(f.rule == "17.7" and f.file == node.name for f in misra.findings(mod.path, mod.name))
