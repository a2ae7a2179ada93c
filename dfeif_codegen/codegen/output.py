"""The output folder out/<model>: what a build may replace there, and replacing it atomically.

A build replaces only what an earlier build wrote (the files its manifest lists, unchanged since:
anything else is the user's and stops it unless --force), and swaps the new folder in by rename,
so a firmware tree that includes it never sees half a module and a failure leaves the old one.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

from dfeif_codegen.codegen.options import BuildError


def _written_before(target: Path) -> set[str]:
    """Files a previous build wrote into target: its manifest and what the manifest lists."""
    try:
        doc = json.loads((target / "manifest.json").read_text(encoding="utf-8"))
        listed = doc.get("files", {}) if isinstance(doc, dict) else {}
        return {"manifest.json", *(str(f) for f in listed)} if isinstance(listed, dict) else set()
    except (OSError, ValueError):
        return set()


def check_target(out_root: Path, name: str, force: bool = False) -> None:
    """Refuse (unless force) to replace anything in out_root/name the toolkit did not write."""
    target = out_root / name
    if out_root.exists() and not out_root.is_dir():
        raise BuildError(f"--out {out_root}: exists and is not a folder")
    if force or not (target.exists() or target.is_symlink()):
        return
    if target.is_symlink() or not target.is_dir():
        raise BuildError(f"{target}: a file the toolkit did not write is in the way (use --force to replace it)")
    ours = _written_before(target)
    if not ours and (target / "manifest.json").is_file():
        raise BuildError(f"{target / 'manifest.json'}: not a manifest codegen build wrote (unreadable JSON), so "
                         "nothing there is known to be the toolkit's; move the folder away or use --force")
    theirs = sorted(p.name for p in target.iterdir() if p.name not in ours or not p.is_file())
    if theirs:
        more = f" and {len(theirs) - 1} more" if len(theirs) > 1 else ""
        raise BuildError(f"{target / theirs[0]}{more}: not written by codegen build (not in manifest.json); "
                         "move it away or use --force")
    edited = _edited_since(target)
    if edited:
        more = f" and {len(edited) - 1} more" if len(edited) > 1 else ""
        raise BuildError(f"{target / edited[0]}{more}: changed since codegen build wrote it (its sha256 is not "
                         "the one in manifest.json); keep the change elsewhere, or use --force to replace it")


def _edited_since(target: Path) -> list[str]:
    """Files of a previous build whose content is no longer what it wrote (a hand edit the next
    build would lose). Line endings are compared as written (LF), so a checkout that turned them
    into CRLF is not an edit."""
    try:
        doc = json.loads((target / "manifest.json").read_text(encoding="utf-8"))
        listed = doc.get("files", {}) if isinstance(doc, dict) else {}
    except (OSError, ValueError):
        return []
    edited = []
    for name, entry in sorted(listed.items()) if isinstance(listed, dict) else ():
        path = target / str(name)
        if not isinstance(entry, dict) or not isinstance(entry.get("sha256"), str) or not path.is_file():
            continue                     # nothing to compare with
        data = path.read_bytes().replace(b"\r\n", b"\n")
        if hashlib.sha256(data).hexdigest() != entry["sha256"]:
            edited.append(str(name))
    return edited


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def _ours(folder: Path, names: set[str]) -> bool:
    """A temp folder a build wrote: regular files only, each one this build writes or its own
    manifest lists, none edited since. A folder merely named like one (a user's backup) is not."""
    if folder.is_symlink() or not folder.is_dir():
        return False
    entries = list(folder.iterdir())
    allowed = names | _written_before(folder)
    return all(p.is_file() and not p.is_symlink() and p.name in allowed for p in entries) \
        and not _edited_since(folder)


def clean_stale(out_root: Path, name: str, names: set[str]) -> None:
    """Temp folders `.NAME.PID.*.new|old` of builds whose process is gone (killed mid-write) and
    whose files are a build's (`_ours`; `names`: what this build writes): an old output whose
    replacement never arrived is put back, the rest removed. Anything else is left alone."""
    if not out_root.is_dir():
        return
    target = out_root / name
    for p in sorted(out_root.glob(f".{name}.*.*")):
        parts = p.name[len(name) + 2:].split(".")
        if len(parts) != 3 or parts[2] not in ("new", "old") or not parts[0].isdigit() or _alive(int(parts[0])) \
                or not _ours(p, names):
            continue
        if parts[2] == "old" and (p / "manifest.json").is_file() and not (target.exists() or target.is_symlink()):
            os.rename(p, target)
        else:
            shutil.rmtree(p, ignore_errors=True)


def _swap(target: Path, tmp: Path, old: Path | None) -> None:
    """target -> old, tmp -> target with SIGINT and SIGTERM held off between the two renames (a
    signal there would leave no output folder, only the hidden old one); delivered after. Also
    recorded by a Python handler: a process-directed signal goes to any thread not blocking it."""
    import signal
    import threading
    held = (signal.SIGINT, signal.SIGTERM)
    pending: list[int] = []
    saved = {}
    if threading.current_thread() is threading.main_thread():
        saved = {s: signal.signal(s, lambda signum, _frame: pending.append(signum)) for s in held}
    masked = hasattr(signal, "pthread_sigmask")
    if masked:
        before = signal.pthread_sigmask(signal.SIG_BLOCK, set(held))
    try:
        if old is not None:
            os.rename(target, old)
        try:
            os.rename(tmp, target)
        except OSError:
            if old is not None and not (target.exists() or target.is_symlink()):
                os.rename(old, target)
            raise
    finally:
        if masked:
            signal.pthread_sigmask(signal.SIG_SETMASK, before)   # a blocked one is recorded now
        for s, handler in saved.items():
            signal.signal(s, handler)
        for signum in dict.fromkeys(pending):
            handler = saved[signal.Signals(signum)]
            if callable(handler):
                handler(signum, None)              # Python's: KeyboardInterrupt for SIGINT
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)        # the default action (SIGTERM ends the process)


def _keep_theirs(target: Path, tmp: Path, files: dict[str, str]) -> None:
    """--force replaces the files a build writes; the user's other files there come along into
    the new folder (copied, so the old folder stays whole until the swap)."""
    for p in target.iterdir():
        if p.name in files:
            continue
        if p.is_dir() and not p.is_symlink():
            shutil.copytree(p, tmp / p.name, symlinks=True)
        else:
            shutil.copy2(p, tmp / p.name, follow_symlinks=False)


class InterruptedAfterWrite(KeyboardInterrupt):
    """A Ctrl-C held off during the output's swap and delivered once the new folder was in
    place: the command stops, but what it wrote is whole (the message says so)."""


def write_atomic(out_root: Path, name: str, files: dict[str, str], force: bool = False,
                 check=None) -> Path:
    """Write files into out_root/name by rendering into a sibling temp folder and renaming.
    `check(folder)` may refuse the new files (BuildError) before they replace the old ones.
    Temp folders carry this process's id, so a later build removes those of a killed one."""
    check_target(out_root, name, force)
    try:
        out_root.mkdir(parents=True, exist_ok=True)
        target = out_root / name
        clean_stale(out_root, name, set(files))
        tmp = Path(tempfile.mkdtemp(prefix=f".{name}.{os.getpid()}.", suffix=".new", dir=out_root))
    except OSError as exc:
        raise BuildError(f"{out_root}: cannot write output ({exc.strerror})") from None
    old = None
    try:
        for fname, text in files.items():
            (tmp / fname).write_bytes(text.encode("utf-8"))
        if force and target.is_dir() and not target.is_symlink():
            _keep_theirs(target, tmp, files)
        os.chmod(tmp, 0o755)
        if check is not None:
            check(tmp)
        if target.exists() or target.is_symlink():
            old = Path(tempfile.mkdtemp(prefix=f".{name}.{os.getpid()}.", suffix=".old", dir=out_root))
            os.rmdir(old)
        _swap(target, tmp, old)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise BuildError(f"{out_root / name}: cannot write output ({exc.strerror})") from None
    except BaseException as exc:       # an interrupt: delivered after the swap, or before it
        written = not tmp.exists() and target.is_dir()
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and old.is_dir() and not old.is_symlink() and target.is_dir():
            shutil.rmtree(old, ignore_errors=True)
        if written and isinstance(exc, KeyboardInterrupt):   # held during the swap: the build is whole
            raise InterruptedAfterWrite(f"after {target} was written (the new build is complete)") from None
        raise
    if old is not None:
        if old.is_dir() and not old.is_symlink():
            shutil.rmtree(old, ignore_errors=True)
        else:
            old.unlink()
    return target
