"""The layout of the generated C, done by the generator itself: lines of at most 100 columns,
long calls, declarations and conditions packed as `templates/.clang-format` lays them out.

Why not run clang-format in the build: its output changes between releases and it may be missing,
while a firmware tree must get the same bytes on every machine. So the templates and the kernel
post-processing emit this layout, and a test checks that clang-format (with the shipped style
file) leaves every generated file unchanged.
"""

from __future__ import annotations

import re

LIMIT = 100
_CALL = re.compile(r"(?:\w|\b(?:if|while|for|switch|return) )\(")
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"|\'(?:[^\'\\]|\\.)*\'')


def pack(head: str, items: list[str], tail: str = "", sep: str = ",", limit: int = LIMIT) -> str:
    """`head item1, item2, ...tail` on one line if it fits in `limit` columns, else the items
    packed greedily onto lines aligned with the first one (head ends with the open parenthesis);
    `sep` ends every item but the last (`,` or an operator such as ` ||`)."""
    pieces = [it + sep for it in items[:-1]] + [items[-1] + tail] if items else [tail]
    one = head + " ".join(pieces)
    if len(one) <= limit:
        return one
    pad = " " * len(head)
    lines, line = [], head
    for piece in pieces:
        if line != head and line != pad and len(line) + 1 + len(piece) > limit:
            lines.append(line)
            line = pad
        if line in (head, pad) and len(line) + len(piece) > limit and _last_space(piece) > 0:
            # a declaration too long even on a line of its own: clang-format breaks it between
            # type and declarator, indents the declarator by 4 and starts the next one anew
            cut = _last_space(piece)
            lines.append(line + piece[:cut])
            lines.append(pad + "    " + piece[cut + 1:])
            line = pad
            continue
        line += piece if line in (head, pad) else " " + piece
    if line != pad:
        lines.append(line)
    return "\n".join(lines)


def _last_space(piece: str) -> int:
    """Index of the last space outside brackets (between a declaration's type and its name), or
    -1 when the piece is not a declaration."""
    masked, depth = _mask(piece), 0
    if '"' in masked or "(" in masked:
        return -1   # a call or a string: not a declaration
    for i in range(len(masked) - 1, -1, -1):
        depth += {"]": 1, "[": -1}.get(masked[i], 0)
        if masked[i] == " " and depth == 0:
            return i
    return -1


def _mask(line: str) -> str:
    """The line with string and character literals blanked, so their brackets do not count."""
    return _STRING.sub(lambda mt: '"' + " " * (len(mt.group(0)) - 2) + '"', line)


def _depth(text: str) -> int:
    masked = _mask(text)
    return masked.count("(") - masked.count(")")


def _split(inner: str, seps: tuple[str, ...]) -> tuple[list[str], str] | None:
    """Split `inner` at the first kind of separator in `seps` found outside brackets."""
    masked = _mask(inner)
    for sep in seps:
        parts, depth, start = [], 0, 0
        i = 0
        while i < len(masked):
            ch = masked[i]
            if ch in "([{":
                depth += 1
            elif ch in ")]}":
                depth -= 1
            elif depth == 0 and masked.startswith(sep, i):
                parts.append(inner[start:i].strip())
                start = i + len(sep)
                i = start
                continue
            i += 1
        if parts:
            return parts + [inner[start:].strip()], sep.rstrip()
    return None


def _repack(statement: str) -> str:
    """One statement (its lines joined) laid out again around its first open parenthesis."""
    indent = statement[: len(statement) - len(statement.lstrip())]
    flat = indent + " ".join(statement.split())
    if len(flat) <= LIMIT:
        return flat
    masked = _mask(flat)
    call = _CALL.search(masked)   # the first call, declaration or condition (not a cast)
    open_at = call.end() - 1 if call else -1
    depth, close_at = 0, -1
    for i in range(open_at, len(masked)):
        depth += {"(": 1, ")": -1}.get(masked[i], 0)
        if depth == 0:
            close_at = i
            break
    if open_at < 0 or close_at < 0:
        return flat
    split = _split(flat[open_at + 1:close_at], (",", " || ", " && "))
    if split is None:
        return flat
    items, sep = split
    return pack(flat[:open_at + 1], items, flat[close_at:], sep)


def lay_out(text: str) -> str:
    """Rejoin and repack every statement whose parentheses span several lines, and any single
    line over the limit; comments, preprocessor lines and everything else pass unchanged."""
    out: list[str] = []
    lines = text.split("\n")
    i = 0
    while i < len(lines):
        line = lines[i]
        code = line.strip()
        if code.startswith(("/*", "*", "//", "#")) or not code:
            out.append(line)
            i += 1
            continue
        stmt, depth = line, _depth(line)
        while depth > 0 and i + 1 < len(lines):
            i += 1
            stmt += "\n" + lines[i]
            depth += _depth(lines[i])
        out.append(_repack(stmt) if ("\n" in stmt or len(stmt) > LIMIT) and "/*" not in stmt else stmt)
        i += 1
    return "\n".join(out)


def single(literal: str) -> str:
    """A decimal literal as single precision: `f` appended, and a value that single precision
    rounds to zero (below half the least subnormal, 2^-150: a process-noise constant of a long chain
    at a short period) written as 0, which is what the compiler would make of it, with a warning."""
    value = float(literal)
    return ("0.0" if 0.0 < abs(value) <= 2.0 ** -150 else literal) + "f"
