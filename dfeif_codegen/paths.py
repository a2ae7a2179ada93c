"""User paths checked before long work starts: output paths a run of minutes must be able to
write, and the text files (models, scenarios) it reads, each refused in one line."""

from __future__ import annotations

import os
import stat
import sys
import tempfile
from pathlib import Path
from typing import Callable

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


def _can_create_in(folder: Path) -> bool:
    """A file can be made in folder: tried (and removed at once), because os.access says yes to
    root on a read-only mount such as /proc."""
    if not folder.is_dir() or not os.access(folder, os.W_OK | os.X_OK):
        return False
    try:
        fd, probe = tempfile.mkstemp(prefix=".codegen-probe-", dir=folder)
    except OSError:
        return False
    os.close(fd)
    os.unlink(probe)
    return True


def writable_file(path: str | Path, flag: str) -> None:
    """`flag PATH`: PATH can be created or replaced as a file (its folder exists)."""
    path = Path(path)
    if str(path) == "":
        raise OutputPathError(f"{flag}: an empty path")
    if path.is_dir():
        raise OutputPathError(f"{flag} {path}: is a folder, not a file")
    parent = path.absolute().parent
    if not parent.is_dir():
        base = _nearest_existing(parent)
        if base.is_dir():
            raise OutputPathError(f"{flag} {path}: its folder {parent} does not exist")
        raise OutputPathError(f"{flag} {path}: cannot create it ({base} is not a writable folder)")
    if path.exists() and not os.access(path, os.W_OK):
        raise OutputPathError(f"{flag} {path}: not writable")
    if not _can_create_in(path.absolute().parent):
        raise OutputPathError(f"{flag} {path}: cannot create it ({path.absolute().parent} is not a writable folder)")


def replaceable_file(path: str | Path, flag: str, command: str, ours: Callable[[Path], bool],
                     inputs: dict | None = None) -> None:
    """`flag PATH` as writable_file, and never a file the toolkit did not write: not one of the
    command's `inputs` ({what: path}, e.g. the scenario it reads), and an existing file only if
    `ours(PATH)` recognises it as this command's earlier output."""
    writable_file(path, flag)
    path = Path(path)
    if not path.exists():
        return
    if not path.is_file():     # a device or FIFO: neither ours nor safe to read to find out
        raise OutputPathError(f"{flag} {path}: exists and is not a regular file; choose another path")
    for what, given in (inputs or {}).items():
        if _same_file(path, given):
            raise OutputPathError(f"{flag} {path}: is the {what} this command reads; choose another path")
    if not ours(path):
        raise OutputPathError(f"{flag} {path}: exists and was not written by codegen {command}; not overwriting "
                              "it: remove it or choose another path")


def _same_file(a: Path, b) -> bool:
    """Whether `b` (a path, or a built-in's name or a model object: no file) is the file `a`."""
    if not isinstance(b, (str, os.PathLike)) or str(b) == "":
        return False
    try:
        return Path(b).is_file() and os.path.samefile(a, b)
    except OSError:
        return False


def first_line(path: Path, limit: int = 2 ** 16) -> str:
    """The first line of a file (at most `limit` bytes of it, decoded leniently; "" when it
    cannot be read): what recognises a toolkit's earlier output without reading all of it."""
    try:
        if not stat.S_ISREG(os.stat(path).st_mode):
            return ""
        with open(path, "rb") as fh:
            head = fh.read(limit)
    except OSError:
        return ""
    return head.split(b"\n", 1)[0].decode("utf-8", "replace").rstrip("\r")


def json_keys(path: Path) -> set:
    """The top-level keys of a JSON object file (empty when it is not one, or over MAX_TABLE_BYTES)."""
    import json

    try:
        doc = json.loads(read_bytes(path, str(path), CodegenError, "JSON", MAX_TABLE_BYTES))
    except (CodegenError, ValueError, RecursionError):
        return set()
    return set(doc) if isinstance(doc, dict) else set()


def writable_dir(path: str | Path, flag: str) -> None:
    """`flag DIR`: DIR exists as a writable folder or can be created."""
    path = Path(path)
    if str(path) == "":
        raise OutputPathError(f"{flag}: an empty path")
    if path.exists() and not path.is_dir():
        raise OutputPathError(f"{flag} {path}: exists and is not a folder")
    base = _nearest_existing(path)
    if not _can_create_in(base):
        raise OutputPathError(f"{flag} {path}: cannot write there ({base} is not a writable folder)")


MAX_TEXT_BYTES = 16 * 2 ** 20   # a model or scenario file: the largest shipped is a few kB
MAX_TABLE_BYTES = 256 * 2 ** 20  # a trajectory CSV: a million steps of a few columns


def read_bytes(path: Path, source: str, error: type[CodegenError], kind: str, limit: int = MAX_TEXT_BYTES) -> bytes:
    """A user's input file's bytes, refused in one line if it is not a regular file (a device
    such as /dev/zero would be read until memory runs out, a FIFO would block forever) or is
    larger than `limit`."""
    try:
        info = os.stat(path)
    except OSError as exc:
        raise error(f"{source}: cannot read {kind} file ({exc.strerror})") from None
    if not stat.S_ISREG(info.st_mode):
        what = "a folder" if stat.S_ISDIR(info.st_mode) else "a device, FIFO or socket"
        raise error(f"{source}: cannot read {kind} file (not a regular file: {what})")
    if info.st_size > limit:
        raise error(f"{source}: {kind} file of {info.st_size} bytes: at most {limit // 2 ** 20} MiB")
    try:
        with open(path, "rb") as fh:
            raw = fh.read(limit + 1)        # bounded even if the file grows meanwhile
    except OSError as exc:
        raise error(f"{source}: cannot read {kind} file ({exc.strerror})") from None
    if len(raw) > limit:
        raise error(f"{source}: {kind} file larger than {limit // 2 ** 20} MiB")
    return raw


def read_text(path: Path, source: str, error: type[CodegenError], kind: str) -> str:
    """A user's text file (a model, a scenario), or one line naming why it cannot be one:
    unreadable, not a regular file, too large, not UTF-8, or binary (a NUL byte)."""
    raw = read_bytes(path, source, error, kind)
    try:
        text = raw.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")   # as open()'s newlines
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
    except RecursionError:
        raise error(f"{source}: malformed TOML: nested too deeply") from None


# every PNG matplotlib saves names it in a tEXt chunk right after the header (docs/figures/*.png)
MATPLOTLIB_PNG = (b"\x89PNG\r\n\x1a\n", b"tEXtSoftware\x00Matplotlib version")


def file_head(path: Path, size: int = 4096) -> bytes:
    """The first `size` bytes of a file (b"" when it cannot be read): enough to recognise what
    wrote it without reading a large file."""
    try:
        with open(path, "rb") as fh:
            return fh.read(size)
    except OSError:
        return b""


def is_matplotlib_png(path: Path) -> bool:
    """A figure one of our commands saved: a PNG written by matplotlib (its magic bytes, then
    matplotlib named in its first chunks). Why no stricter mark: the committed figures carry
    none, and a user's file of that name is a photo, a diagram or notes, not a matplotlib PNG."""
    head = file_head(path, 256)
    return head.startswith(MATPLOTLIB_PNG[0]) and MATPLOTLIB_PNG[1] in head


def check_figure_paths(folder: Path, names: list[str], flag: str, command: str) -> None:
    """Each figure `folder/name` a command will save: new, or a figure saved earlier (a
    matplotlib PNG), never a user's file of the same name. A missing folder is made empty."""
    for name in names:
        target = Path(folder) / name
        if target.parent.is_dir():
            replaceable_file(target, flag, command, is_matplotlib_png)
