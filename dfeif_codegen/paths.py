"""User paths checked before long work starts: output paths a run of minutes must be able to
write, and the text files (models, scenarios) it reads, each refused in one line."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from dfeif_codegen.errors import CodegenError

if sys.version_info >= (3, 11):  # the standard library's TOML reader from Python 3.11, its backport before
    import tomllib  # novermin
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


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


def read_text(path: Path, source: str, error: type[CodegenError], kind: str) -> str:
    """A user's text file (a model, a scenario), or one line naming why it cannot be one:
    unreadable, not UTF-8, or binary (a NUL byte)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise error(f"{source}: cannot read {kind} file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise error(f"{source}: not a UTF-8 text file (byte {exc.start})") from None
    if "\x00" in text:
        raise error(f"{source}: not a text file (NUL byte at character {text.index(chr(0))})")
    return text


def parse_toml(text: str, source: str, error: type[CodegenError]) -> dict:
    """TOML text as a dict, or one line naming the file and the syntax error."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{source}: malformed TOML: {exc}") from None

