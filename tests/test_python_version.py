"""The `requires-python` claim holds: vermin finds nothing in the package that needs a newer
Python than the oldest one pyproject.toml admits (e.g. tomllib without its tomli fallback)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from conftest import require_module

ROOT = Path(__file__).resolve().parents[1]


def test_package_runs_on_the_oldest_python_claimed():
    claim = re.search(r'^requires-python = ">=(3\.\d+)"$', (ROOT / "pyproject.toml").read_text(), re.M)
    assert claim, "pyproject.toml: requires-python must be a lower bound '>=3.N'"
    require_module("vermin")
    run_vermin = "import sys, vermin; sys.exit(vermin.main())"
    proc = subprocess.run([sys.executable, "-c", run_vermin, f"-t={claim.group(1)}-", "--no-tips", "--violations",
                           "dfeif_codegen"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    found = re.search(r"Minimum required versions: (\d+)\.(\d+)", proc.stdout)
    assert found, proc.stdout
    assert (int(found.group(1)), int(found.group(2))) <= tuple(map(int, claim.group(1).split("."))), proc.stdout
