"""MISRA C:2012 findings of a generated module, from `cppcheck --addon=misra`, per rule.

Debian's cppcheck ships the MISRA addon without the rule texts (they are sold by MISRA), so it
reports rule numbers only: that is enough to count findings per rule and to tell the code the
templates write from the kernel bodies CasADi prints. `docs/misra.md` is this report for the
built-in models (regenerate it with `python -m dfeif_codegen.check.misra`).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from dfeif_codegen.errors import SetupError

_LINE = re.compile(r"^(?P<file>[^:\n]+):(?P<line>\d+):misra-c2012-(?P<rule>\d+\.\d+)$", re.M)

# Advisory rules the generated library deviates from, and why (docs/misra.md repeats these).
DEVIATIONS = {
    "2.3": "the compile-time checks are typedefs of arrays whose size is negative when a build "
           "option is out of range; they are never used, by design",
    "2.5": "the public header defines the dimensions, options and indices for the caller; the "
           "library itself does not need every one of them",
    "8.7": "the wire's packet and command decoders are public API for the application (the "
           "node and master programs decode with them); inside the library one file calls them",
    "8.9": "the table of output indices is shared by the node, the master and the controller "
           "through the internal header, though each file uses it in one function; the wire's "
           "constant tables (CRC-32 nibbles, model hash prefix) sit at file scope next to the "
           "format they define",
    "12.1": "cppcheck asks for parentheses around every comparison inside && or || and every "
            "product inside a sum (`i * n + j`); the conditions and indices rely on C's usual "
            "precedence, which the compilers' -Wparentheses checks where it is easy to misread",
    "15.5": "a function returns an error code as soon as a check fails, before it writes "
            "anything: the early return is what keeps the state unchanged on bad input",
}

# Reported by cppcheck 2.10, but not a violation of the rule in this code.
NOT_VIOLATIONS = {
    "2.2": "`x * NY` and `NY * NY` with NY = 1 (one flat output) are reported as dead code; the "
           "templates are the same for every model and the report disappears for NY > 1",
    "12.3": "a declaration of several variables (`int i, j;`) is reported as a comma operator; "
            "a declarator list has no comma operator",
}

# Findings expected in the CasADi kernel bodies, and why (none today).
KERNEL_FINDINGS: dict[str, str] = {}


@dataclass(frozen=True)
class Finding:
    file: str
    line: int
    rule: str

    @property
    def kernel(self) -> bool:
        """In a file of CasADi kernel bodies (post-processed, but not written by a template)."""
        return "_kernels_" in self.file


def rule_key(rule: str) -> tuple[int, int]:
    major, minor = rule.split(".")
    return int(major), int(minor)


def findings(folder: Path, name: str) -> list[Finding]:
    """cppcheck --addon=misra over the library sources of a module (the example is excluded:
    it is a host demo that uses stdio)."""
    cppcheck = shutil.which("cppcheck")
    if cppcheck is None:
        raise SetupError("cppcheck not found: install the Debian package cppcheck (apt-get install cppcheck)")
    sources = sorted(str(p) for p in Path(folder).glob(f"{name}_*.c"))
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.run([cppcheck, "--addon=misra", "--std=c99", "--language=c", "--quiet",
                               f"--cppcheck-build-dir={tmp}", "--template={file}:{line}:{id}",
                               "-I", str(folder), *sources], capture_output=True, text=True, timeout=900)
    text = proc.stdout + proc.stderr
    out = [Finding(Path(m["file"]).name, int(m["line"]), m["rule"]) for m in _LINE.finditer(text)]
    other = [ln for ln in text.splitlines() if ln.strip() and not _LINE.match(ln)]
    if proc.returncode != 0 or other:
        raise SetupError("cppcheck failed: " + " | ".join(other[:5]))
    return sorted(set(out), key=lambda f: (f.file, f.line, rule_key(f.rule)))


def per_rule(found: list[Finding]) -> dict[str, tuple[int, int]]:
    """rule -> (findings in template-written code, findings in kernel bodies)."""
    tmpl = Counter(f.rule for f in found if not f.kernel)
    kern = Counter(f.rule for f in found if f.kernel)
    return {r: (tmpl[r], kern[r]) for r in sorted(set(tmpl) | set(kern), key=rule_key)}


def status(rule: str) -> str:
    if rule in DEVIATIONS:
        return "advisory, deviation"
    if rule in NOT_VIOLATIONS:
        return "tool report, not a violation"
    return "**unexplained**"


def report(modules: dict[str, tuple[Path, str]], version: str) -> str:
    """docs/misra.md for {label: (folder, model name)}: the per-rule table and the reasons."""
    lines = ["# MISRA C:2012 check of the generated C", "",
             "Generated by `python -m dfeif_codegen.check.misra docs/misra.md` with " + version + ",",
             "`--addon=misra` without the rule texts (so by rule number only), over the library",
             "sources of each module (the host example, which uses stdio, is left out). Counts are",
             "findings in the code the templates write and in the kernel bodies CasADi prints.",
             "tests/test_misra.py checks that every rule found is explained below.", ""]
    for label, (folder, name) in modules.items():
        counts = per_rule(findings(folder, name))
        lines += [f"## {label}", "", "| rule | templates | kernels | status |", "|---|---|---|---|"]
        lines += [f"| {rule} | {t} | {k} | {status(rule)} |" for rule, (t, k) in counts.items()]
        if not counts:
            lines.append("| (none) | 0 | 0 | |")
        lines.append("")
    lines += ["## Deviations (advisory rules)", ""]
    lines += [f"- **{r}**: {why}." for r, why in sorted(DEVIATIONS.items(), key=lambda kv: rule_key(kv[0]))]
    lines += ["", "## Reported, but not violations", ""]
    lines += [f"- **{r}**: {why}." for r, why in sorted(NOT_VIOLATIONS.items(), key=lambda kv: rule_key(kv[0]))]
    lines += ["", "## Kernel bodies", "",
              "The CasADi kernels are straight-line assignments to a work array: no finding in the",
              "variants above (their helpers are renamed per file for rule 5.9)." if not KERNEL_FINDINGS else
              "\n".join(f"- **{r}**: {why}." for r, why in KERNEL_FINDINGS.items())]
    return "\n".join(lines) + "\n"


def cppcheck_version() -> str:
    cppcheck = shutil.which("cppcheck")
    if cppcheck is None:
        raise SetupError("cppcheck not found: install the Debian package cppcheck (apt-get install cppcheck)")
    return subprocess.run([cppcheck, "--version"], capture_output=True, text=True).stdout.strip()


VARIANTS = {
    "dc_motor_link, default options": ("dc_motor_link", {}),
    "dc_motor_link, float, retrodict, ci, 3 nodes":
        ("dc_motor_link", {"precision": "float", "oosm": "retrodict", "fusion": "ci", "nodes": 3}),
    "two_link_arm, default options": ("two_link_arm", {}),
    "two_link_arm, float, retrodict, paper":
        ("two_link_arm", {"precision": "float", "oosm": "retrodict", "fusion": "paper"}),
}


def main(argv: list[str] | None = None) -> int:
    """Build the built-in models in a temporary folder and print (or write) the report."""
    from dfeif_codegen.codegen import build

    argv = sys.argv[1:] if argv is None else argv
    with tempfile.TemporaryDirectory() as tmp:
        modules = {}
        for i, (label, (model_name, opts)) in enumerate(VARIANTS.items()):
            mod = build.build(model_name, Path(tmp) / str(i), **opts)
            modules[label] = (mod.path, mod.name)
        text = report(modules, cppcheck_version())
    if argv:
        Path(argv[0]).write_text(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
