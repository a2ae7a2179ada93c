"""Documentation and comments are self-contained: no path that leaves the repository, and every
repository path they cite exists (a renamed module or document breaks this test, not a reader)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TEXT = {".py", ".md", ".j2", ".toml", ".sh", ".c", ".h", ".txt", ".json", ".mk", ".ld", ".cfg", ".yml", ".yaml"}
# notes kept beside the repository (the steering folders), or the machine it was written on
OUTSIDE = re.compile(r"equations\.md|(?<![\w.])shared/|steering repo|(?<![\w.])/work/")
CLIMB = re.compile(r"(?:\.\./)+[\w.-][\w./-]*")
CITED = re.compile(r"(?<![\w/.<{-])((?:docs|templates|dfeif_codegen|tests|scripts)/[\w/.-]*\w\.(?:md|py|j2|toml|sh))\b")


def text_files() -> list[Path]:
    """The repository's files (git's list when it is a checkout, else a walk), text types only."""
    try:
        names = subprocess.run(["git", "ls-files", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                               capture_output=True, text=True, check=True).stdout.splitlines()
        paths = [ROOT / n for n in names]
    except (OSError, subprocess.CalledProcessError):
        paths = [p for p in ROOT.rglob("*") if not any(part.startswith(".") for part in p.relative_to(ROOT).parts)]
    me = Path(__file__).resolve()
    return [p for p in paths if p.suffix in TEXT and p.is_file() and p.resolve() != me]


def test_no_reference_leaves_the_repository():
    bad = []
    for path in text_files():
        text = path.read_text(errors="replace")
        for hit in OUTSIDE.finditer(text):
            bad.append(f"{path.relative_to(ROOT)}:{text.count(chr(10), 0, hit.start()) + 1}: {hit.group()}")
        for hit in CLIMB.finditer(text):
            target = (path.parent / hit.group()).resolve()
            if not target.is_relative_to(ROOT):
                bad.append(f"{path.relative_to(ROOT)}:{text.count(chr(10), 0, hit.start()) + 1}: {hit.group()}")
    assert bad == []


def test_every_cited_repository_path_exists():
    missing = []
    for path in text_files():
        if path.is_relative_to(ROOT / "generated"):
            continue
        for hit in CITED.finditer(path.read_text(errors="replace")):
            if not (ROOT / hit.group(1)).exists():
                missing.append(f"{path.relative_to(ROOT)}: {hit.group(1)}")
    assert missing == []


def test_the_mathematics_is_written_down():
    """docs/mathematics.md states each step the code implements (the headings a reader looks for)."""
    text = (ROOT / "docs" / "mathematics.md").read_text()
    headings = [h.lower() for h in re.findall(r"^## (.+)$", text, re.M)]
    for topic in ("flatness", "discretization", "kalman filter", "late measurements", "fusion", "control"):
        assert any(topic in h for h in headings), topic
    for term in ("Lie derivative", "Brunovsky", "retrodiction", "Replay", "covariance intersection", "Q_d"):
        assert term.lower() in text.lower(), term
