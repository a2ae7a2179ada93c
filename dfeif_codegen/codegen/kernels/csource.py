"""CasADi's C text post-processed into one file per kernel group (`c_source`).

Internal helpers are made `static` and named per file, each entry point a typed function
`<model>_kern_<name>` whose named, sized parameters come from the kernel's signature (so callers
never fill `arg[]`/`res[]` by position), statements spaced as the style file asks, the real type
named, and, for single precision, `f` math calls and `f` literals so that no double arithmetic
hides in a float build. A kernel can instead be printed as C loops over static parts (`Loop`) or
as a call of another kernel on packed copies (`packed_wrapper`). Nothing here knows the model.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import casadi as ca

from dfeif_codegen.codegen import layout

_MATH = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log",
         "sqrt", "ceil", "floor", "fabs", "fmin", "fmax", "pow", "fmod", "erf", "copysign", "hypot",
         "log10", "log1p", "expm1", "trunc", "round", "cbrt", "asinh", "acosh", "atanh")
_MATH_CALL = re.compile(r"(?<![\w.])(" + "|".join(_MATH) + r")\(")
_FLOAT_LIT = re.compile(r"(?<![\w.])(\d+\.\d*(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)(?![\w.])")
_ENTRY = re.compile(r"^int (\w+)\(const casadi_real\*\* arg, casadi_real\*\* res, casadi_int\* iw, "
                    r"casadi_real\* w, int mem\)\{\n  return (casadi_f\d+)\(arg, res, iw, w, mem\);\n\}$", re.M)
_BODY = re.compile(r"^(/\* [^\n]*\*/\n)static int (casadi_f\d+)\(const casadi_real\*\* arg, casadi_real\*\* res, "
                   r"casadi_int\* iw, casadi_real\* w, int mem\) \{\n(.*?)^\}\n", re.M | re.S)
_HELPER = re.compile(r"^casadi_real (casadi_\w+)\(([^)\n]*)\) \{(?: ([^\n]*)\}\n|\n/\* Pre-c99 compatibility \*/\n"
                     r"#if __STDC_VERSION__ < 199901L\n[^\n]*\n#else\n([^\n]*)\n#endif\n\}\n)", re.M)
_ANY_HELPER = re.compile(r"^casadi_real casadi_\w+\(", re.M)
_CONST = re.compile(r"^static const casadi_(?:real|int) (casadi_[cs]\d+)\[\d+\] = \{[^}]*\};\n", re.M)
_TOKEN = re.compile(r"\s*(\d+\.\d*(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+|\d+|\w+|==|!=|<=|>=|&&|\|\||\S)")
_BINARY = {"+", "-", "*", "/", "=", "<", ">", "==", "!=", "<=", ">=", "&&", "||", "?", ":"}
_C_KEYWORDS = {"auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else",
               "enum", "extern", "float", "for", "goto", "if", "inline", "int", "long", "register",
               "restrict", "return", "short", "signed", "sizeof", "static", "struct", "switch", "typedef",
               "union", "unsigned", "void", "volatile", "while", "free", "w"}
INDENT = "    "


@dataclass
class KernelC:
    """One kernel's typed C entry point: its named, sized inputs and outputs and its work size."""

    name: str
    signature: str      # CasADi's one-line description, e.g. "predict:(x[3],P[3x3],...)->(...)"
    sz_w: int
    inputs: list[tuple[str, int]]
    outputs: list[tuple[str, int]]
    local_work: bool = False

    def parameters(self, real: str, work: str | None = None) -> list[str]:
        """The C parameter list: inputs const, outputs writable, every array sized, then the work
        (its size is also <NAME>_SZ_W in the kernels header, for the callers; `work` names that
        macro in the prototype, so the header uses every size it defines), unless the kernel
        keeps its work in locals."""
        # a C array has at least one element: an empty input (a model without parameters) is [1]
        return ([f"const {real} {n}[{max(k, 1)}]" for n, k in self.inputs] + [f"{real} {n}[{k}]" for n, k in self.outputs]
                + ([] if self.local_work else [f"{real} w[{work or self.sz_w}]"]))


@dataclass
class Loop:
    """A kernel printed as C loops over straight-line parts (`parts`, static in its file, each
    O(n^2) code) instead of its own straight-line code, which is Theta(n^3) bytes for Theta(n^3)
    operations. `decls` and `body`: the C between the parameters and the return (`casadi_real`
    names the real type); the kernel's own ca.Function still gives its signature."""

    parts: list[ca.Function]
    decls: list[str]
    body: list[str]


def for_lines(head: str, body: list[str]) -> list[str]:
    """A C for loop as lines: `for (head) {`, the body indented, `}`."""
    return [f"for ({head}) {{"] + [INDENT + line for line in body] + ["}"]


def float_text(text: str) -> str:
    """Single precision: `f` math calls and `f` literals."""
    text = _MATH_CALL.sub(lambda mt: mt.group(1) + "f(", text)
    return _FLOAT_LIT.sub(lambda mt: layout.single(mt.group(1)), text)


def spaced(statement: str) -> str:
    """One C expression statement spaced as clang-format does: binary operators and `=` between
    spaces, unary signs and calls tight, `, ` after commas. CasADi prints no spaces at all."""
    tokens = _TOKEN.findall(statement)
    out, prev = "", None
    for tok in tokens:
        unary = tok in ("-", "+") and (prev is None or prev in _BINARY | {"(", "[", ",", "return"}
                                       or prev in ("!",))
        if tok == ",":
            out += ", "
        elif tok in _BINARY and not unary:
            out = out.rstrip(" ") + f" {tok} "
        elif tok in (")", "]", ";"):
            out = out.rstrip(" ") + tok
        elif tok == "return":
            out += "return "
        else:
            out += tok
        prev = tok
    return out.strip()


def wrap_comment(text: str, width: int = 94) -> str:
    """A one-line description cut into comment lines (` * ` continuations) of at most `width`."""
    lines, line = [], ""
    for piece in re.split(r"(?<=,)", text):
        if line and len(line + piece) > width:
            lines.append(line)
            line = ""
        line += piece
    lines.append(line)
    return "\n * ".join(lines)


def _function(head: str, params: list[str], body: list[str]) -> str:
    """A C function definition laid out as the style file asks (see codegen/layout.py)."""
    return layout.pack(head + "(", params, ")") + "\n{\n" + "".join(INDENT + line + "\n" for line in body) + "}\n"


def _arguments(f: ca.Function) -> tuple[list[tuple[str, int]], list[tuple[str, int]]]:
    """A kernel's inputs and outputs as (name, number of entries)."""
    return ([(f.name_in(i), f.numel_in(i)) for i in range(f.n_in())],
            [(f.name_out(i), f.numel_out(i)) for i in range(f.n_out())])


def _casadi_text(functions: list[ca.Function]) -> tuple[str, dict[str, str], list[tuple[str, str, str]]]:
    """CasADi's C for the functions: the whole text, its entry -> body function names, and each
    body as (comment, body function, statements). Fails on a layout this module does not know."""
    cg = ca.CodeGenerator("kernels", {"casadi_int": "int", "casadi_real": "double", "avoid_stack": True,
                                      "main": False, "mex": False, "with_header": False,
                                      "with_export": False, "verbose": False, "include_math": True})
    for f in functions:
        cg.add(f)
    text = cg.dump()
    entries = {fn: name for name, fn in _ENTRY.findall(text)}
    bodies = _BODY.findall(text)
    if len(bodies) != len(functions) or len(entries) != len(functions):
        raise RuntimeError("unexpected CasADi output layout (kernel bodies not found)")
    if len(_HELPER.findall(text)) != len(_ANY_HELPER.findall(text)):
        raise RuntimeError("unexpected CasADi output layout (a helper of an unknown form)")
    return text, entries, bodies


def _helpers(text: str, real: str) -> tuple[list[str], str]:
    """CasADi's helpers (`casadi_sq`, ...) as static functions, and their text as CasADi printed it."""
    out, used = [], ""
    for mt in _HELPER.finditer(text):
        helper, args, one_line, c99 = mt.groups()   # a one-line body, or the C99 branch of an #if
        stmt = one_line if one_line is not None else c99
        args = re.sub(r"\bcasadi_real\b", real, args)
        out.append(_function(f"static {real} {helper}", [a.strip() for a in args.split(",")],
                             [spaced(s) + ";" for s in stmt.split(";") if s.strip()]))
        used += mt.group(0)
    return out, used


def _named_body(f: ca.Function, body: str) -> str:
    """A kernel body with its arguments named: CasADi's NULL checks dropped (every input and
    output is passed) and its float-to-bool conversions made comparisons."""
    name = f.name()
    if re.search(r"\b(iw|mem)\b|\bcasadi_f\d+\(", body) or f.sz_iw() != 0:
        raise RuntimeError(f"kernel {name}: integer work or a nested call, unexpected for SX")
    ins, outs = _arguments(f)
    names = [n for n, _ in ins + outs]
    if len(set(names)) != len(names) or set(names) & _C_KEYWORDS:
        raise RuntimeError(f"kernel {name}: argument names must be distinct C identifiers, not w")
    # `!x` and `x ? :` on a real are float-to-bool conversions (clang -Wfloat-conversion)
    body = re.sub(r"\(!(w\[\d+\])\)", r"(\1==0)", body)
    body = re.sub(r"\((w\[\d+\])\?", r"(\1!=0?", body)
    body = re.sub(r"arg\[(\d+)\]\? (arg\[\1\]\[\d+\]) : 0", r"\2", body)
    body = re.sub(r"if \(res\[(\d+)\]!=0\) (res\[\1\]\[\d+\]=)", r"\2", body)
    body = re.sub(r"\barg\[(\d+)\]\[", lambda mt: ins[int(mt.group(1))][0] + "[", body)
    body = re.sub(r"\bres\[(\d+)\]\[", lambda mt: outs[int(mt.group(1))][0] + "[", body)
    if re.search(r"\b(arg|res)\b", body):
        raise RuntimeError(f"kernel {name}: unexpected CasADi argument pattern")
    return body


def _straight_line(comment: str, f: ca.Function, body: str, real: str, registers: bool, own_work: bool,
                   static: bool) -> tuple[str, KernelC]:
    """One kernel's typed C from CasADi's body. `registers`: one scalar per work entry (the
    compiler keeps them in registers); `own_work`: one local work array; else a work parameter."""
    ins, outs = _arguments(f)
    info = KernelC(f.name(), comment[3:-4], max(1, f.sz_w()), ins, outs, registers or own_work)
    lines = [spaced(line.strip()) for line in _named_body(f, body).splitlines() if line.strip()]
    if registers:
        lines = [f"casadi_real w{i};" for i in range(info.sz_w)] + [re.sub(r"\bw\[(\d+)\]", r"w\1", line)
                                                                 for line in lines]
    elif own_work:
        lines.insert(0, f"casadi_real w[{info.sz_w}];")
    # an input the expressions never read (an empty one; the held predictor's centre when F and G
    # do not depend on the heads): a cast, or -Wunused-parameter
    lines = [f"(void){n};" for n, k in ins if k == 0 or not any(re.search(rf"\b{n}\[", ln) for ln in lines)] + lines
    lines.append("return 0;")
    text = f"/* {wrap_comment(info.signature)} */\n" + _function(f"{'static ' if static else ''}int {f.name()}",
                                                                  info.parameters(real), lines)
    return text, info


def _looped(f: ca.Function, loop: Loop, real: str) -> tuple[str, KernelC]:
    """A kernel's typed C as the loops of `loop` (its parts are printed as static kernels)."""
    info = KernelC(f.name(), str(f).rsplit(" ", 1)[0], 1, *_arguments(f), True)
    text = f"/* {wrap_comment(info.signature)} */\n" + _function(
        f"int {f.name()}", info.parameters(real), loop.decls + loop.body + ["return 0;"])
    return text, info


def c_source(functions: list[ca.Function], real: str, precision: str,
             helpers: str = "casadi", local_work: bool = False,
             wrappers: dict[str, str] | None = None,
             loops: dict[str, Loop] | None = None,
             own_work: set[str] | frozenset[str] = frozenset()) -> tuple[str, list[KernelC]]:
    """C for a group of kernels: helpers `static`, one typed entry point per kernel
    `int name(const real in1[k1], ..., real out1[j1], ..., real w[SZ_W])`, spaced like clang-format;
    CasADi's helpers (`casadi_sq`, ...) renamed `<helpers>_sq`.

    Why typed: callers name each argument and the compiler checks its type, instead of filling
    `arg[]`/`res[]` by position; and no array of pointers is left to get wrong.
    `local_work`: the work is local scalars instead of the last parameter; it cannot alias the
    arguments, so the compiler keeps it in registers (the master's kernels use this).
    `own_work`: kernels whose work is one local array instead of a parameter (same reason).
    `wrappers`: kernels printed as `packed_wrapper` calls of another kernel of the group.
    `loops`: kernels printed as C loops over their parts (`Loop`), the parts static."""
    wrappers, loops = wrappers or {}, loops or {}
    looped = [f for f in functions if f.name() in loops]
    parts = {g.name() for f in looped for g in loops[f.name()].parts}
    functions = functions + [g for f in looped for g in loops[f.name()].parts]
    by_name = {f.name(): f for f in functions}
    wrapped = [f for f in functions if f.name() in wrappers]
    functions = [f for f in functions if f.name() not in wrappers and f.name() not in loops]
    text, entries, bodies = _casadi_text(functions)
    out, used = _helpers(text, real)
    used += "".join(body for _, _, body in bodies)
    for mt in _CONST.finditer(text):
        if re.search(rf"\b{mt.group(1)}\b", used):
            raise RuntimeError(f"unexpected CasADi constant table {mt.group(1)} in an SX kernel")
    infos = []
    for comment, fn, body in bodies:
        name = entries[fn]
        code, info = _straight_line(comment, by_name[name], body, real, local_work,
                                    name in own_work or name in parts, name in parts)
        out.append(code)
        if name not in parts:
            infos.append(info)
    for f in looped:
        code, info = _looped(f, loops[f.name()], real)
        out.append(code)
        infos.append(info)
    for f in wrapped:
        info, code = packed_wrapper(f, by_name[wrappers[f.name()]], real)
        out.append(code)
        infos.append(info)
    code = "\n".join(out)
    # static helpers named per file (unique across the library); a group with a packed wrapper
    # keeps CasADi's names, as the generator always has (static, so no clash at link time)
    for mt in _HELPER.finditer("" if wrapped else text):
        code = re.sub(rf"\b{mt.group(1)}\b", helpers + mt.group(1)[len("casadi"):], code)
    code = re.sub(r"\bcasadi_real\b", real, code)
    code = re.sub(r"\bcasadi_int\b", "int", code)
    if precision == "float":
        code = float_text(code)
    return code, infos


def packed_wrapper(f: ca.Function, target: ca.Function, real: str) -> tuple[KernelC, str]:
    """C for kernel f as a call of `target` on packed copies. Each of target's arguments is made of
    the next of f's, in order: one passed through when the sizes agree, else several copied into
    one buffer, an n x n one as its upper triangle (CasADi's entry (i, j), i <= j, at i + j n), as
    the node keeps a state [x; P packed]; each packed result is unpacked into both triangles.
    Same expressions, so the same results bit for bit."""
    ins, outs = _arguments(f)
    t_ins = [(target.name_in(i), target.numel_in(i)) for i in range(target.n_in())]
    t_outs = [target.numel_out(i) for i in range(target.n_out())]
    if ins == t_ins or len(outs) != len(t_outs):
        raise RuntimeError(f"kernel {f.name()}: no packed counterpart in {target.name()}")

    square = {f.name_in(i) for i in range(f.n_in()) if f.size1_in(i) == f.size2_in(i) > 1}

    def packed_size(arg: str, k: int, kt: int) -> int:   # k entries of f stored in target's form
        if k == kt or arg not in square:
            return k
        n = math.isqrt(k)
        return n * (n + 1) // 2

    def loop(n: int, body: list[str]) -> list[str]:   # k runs over the packed entries (packed_index)
        return (["k = 0;", f"for (j = 0; j < {n}; j++) {{", INDENT + "for (i = 0; i <= j; i++) {"]
                + [2 * INDENT + b for b in body + ["k++;"]] + [INDENT + "}", "}"])

    decls, pack, unpack, args = [], [], [], []
    pending = list(ins)
    for t_arg, kt in t_ins:
        if pending and pending[0][1] == kt:
            args.append(pending.pop(0)[0])
            continue
        buf, filled = f"{t_arg}_packed", 0
        decls.append(f"casadi_real {buf}[{kt}];")
        args.append(buf)
        while filled < kt:
            if not pending:
                raise RuntimeError(f"kernel {f.name()}: its arguments do not fill {target.name()}'s {t_arg}")
            arg, k = pending.pop(0)
            size = packed_size(arg, k, kt - filled)
            if size == k:
                at = f"{filled} + i" if filled else "i"
                pack += [f"for (i = 0; i < {k}; i++) {{", INDENT + f"{buf}[{at}] = {arg}[i];", "}"]
            else:
                n = math.isqrt(k)
                at = f"{filled} + k" if filled else "k"
                pack += loop(n, [f"{buf}[{at}] = {arg}[(j * {n}) + i];"])
            filled += size
        if filled != kt:
            raise RuntimeError(f"kernel {f.name()}: its arguments overfill {target.name()}'s {t_arg}")
    if pending:
        raise RuntimeError(f"kernel {f.name()}: arguments left over for {target.name()}")
    for (arg, k), kt in zip(outs, t_outs):
        if k == kt:
            args.append(arg)
            continue
        n = math.isqrt(k)
        if n * n != k or n * (n + 1) // 2 != kt:
            raise RuntimeError(f"kernel {f.name()}: result {arg} is not the square of {target.name()}'s")
        decls.append(f"casadi_real {arg}_packed[{kt}];")
        args.append(f"{arg}_packed")
        unpack += loop(n, [f"{arg}[(j * {n}) + i] = {arg}_packed[k];", f"{arg}[(i * {n}) + j] = {arg}_packed[k];"])
    lines = decls + ["int i;", "int j;", "int k;"] + pack + [f"(void){target.name()}({', '.join(args)});"]
    lines += unpack + ["return 0;"]
    info = KernelC(f.name(), str(f).rsplit(" ", 1)[0], 1, ins, outs, True)
    text = f"/* {wrap_comment(info.signature)} */\n" + _function(f"int {f.name()}", info.parameters(real), lines)
    return info, re.sub(r"\bcasadi_real\b", real, text)
