"""Output paths checked before long work starts: a run of minutes must not end in 'cannot write'."""

from __future__ import annotations

import os
from pathlib import Path

from dfeif_codegen.errors import CodegenError


class OutputPathError(CodegenError):
    """An output file or folder the command would not be able to write."""


def _nearest_existing(path: Path) -> Path:
    path = path.absolute()
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def writable_file(path: str | Path, flag: str) -> None:
    """`flag PATH`: PATH can be created or replaced as a file."""
    path = Path(path)
    if path.is_dir():
        raise OutputPathError(f"{flag} {path}: is a folder, not a file")
    base = _nearest_existing(path.parent)
    if path.exists() and not os.access(path, os.W_OK):
        raise OutputPathError(f"{flag} {path}: not writable")
    if not base.is_dir() or not os.access(base, os.W_OK | os.X_OK):
        raise OutputPathError(f"{flag} {path}: cannot create it ({base} is not a writable folder)")


def writable_dir(path: str | Path, flag: str) -> None:
    """`flag DIR`: DIR exists as a writable folder or can be created."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputPathError(f"{flag} {path}: exists and is not a folder")
    base = _nearest_existing(path)
    if not base.is_dir() or not os.access(base, os.W_OK | os.X_OK):
        raise OutputPathError(f"{flag} {path}: cannot write there ({base} is not a writable folder)")
