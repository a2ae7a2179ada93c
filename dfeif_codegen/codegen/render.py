"""Render the firmware module: one Jinja2 template per output file, all from one context dict.

Why strict: `StrictUndefined` turns a misspelled or missing context key into a build error instead
of silently empty C. Templates are package data (`dfeif_codegen.templates`), read through
`importlib.resources`, so an installed wheel renders exactly what the source tree does.
"""

from __future__ import annotations

import hashlib
from importlib import resources
from typing import Any

import jinja2

from dfeif_codegen.codegen import layout

# (template, output file name; {p} is the model name, {group} a kernel group). The node and the
# master have one template per late-measurement method and per fusion rule ({oosm}, {fusion}),
# each extending the shared node.c.j2 or master.c.j2 with its own blocks.
LIBRARY = [
    ("model.h.j2", "{p}.h"),
    ("kernels.h.j2", "{p}_kernels.h"),
    ("internal.h.j2", "{p}_internal.h"),
    ("node_{oosm}.c.j2", "{p}_node.c"),
    ("master_{fusion}.c.j2", "{p}_master.c"),
    ("control.c.j2", "{p}_control.c"),
    ("wire.c.j2", "{p}_wire.c"),
]
KERNELS = ("kernels.c.j2", "{p}_kernels_{group}.c")
PROJECT = [
    ("CMakeLists.txt.j2", "CMakeLists.txt"),
    ("model.mk.j2", "{p}.mk"),
    ("example_main.c.j2", "example_main.c"),
]
MANIFEST = ("manifest.json.j2", "manifest.json")


def _load(name: str) -> tuple[str, str, Any]:
    text = (resources.files("dfeif_codegen.templates") / name).read_text(encoding="utf-8")
    return text, name, lambda: True


def literal(precision: str):
    """A C literal of the build's real type: `0.01` or `0.01f` (no hidden double in float builds)."""
    def lit(value: float) -> str:
        text = repr(float(value))
        if "e" not in text and "." not in text and "inf" not in text and "nan" not in text:
            text += ".0"
        return layout.single(text) if precision == "float" else text
    return lit


def environment(precision: str = "double") -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.FunctionLoader(_load), undefined=jinja2.StrictUndefined,
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             autoescape=False)
    env.filters["lit"] = literal(precision)
    env.filters["comment"] = comment
    return env


def banner(template: str, model: str, version: str, flags: str = "", command: str | None = None) -> str:
    """`flags`: the build's non-default options, so that the command regenerates this build;
    `command`: the whole command instead (a model file's name is not the model's)."""
    command = command or f"codegen build {' '.join([model, flags]).strip()}"
    return (f"DO NOT EDIT: {model} module, generated from template {template} by dfeif-codegen "
            f"{version}; regenerate with `{command}`.")


def comment(text: str, continuation: str = " * ", width: int = 94) -> str:
    """Text wrapped at word boundaries into comment lines joined by `continuation`."""
    lines, line = [], ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    lines.append(line)
    return ("\n" + continuation).join(lines)


def file_names(p: str, groups: list[str]) -> list[str]:
    """Every file `render` writes, in a stable order (the library sources first)."""
    names = [out.format(p=p) for _, out in LIBRARY]
    names += [KERNELS[1].format(p=p, group=g) for g in groups]
    return names + [out.format(p=p) for _, out in PROJECT] + [MANIFEST[1]]


def render(context: dict[str, Any]) -> dict[str, str]:
    """Context -> {file name: text}. `context["kernel_code"]` maps group -> post-processed C;
    the manifest is rendered last, with the size and hash of every other file."""
    env = environment(context["opts"].precision)
    p, version = context["p"], context["versions"]["dfeif-codegen"]
    opts = context["opts"]
    # the model as `codegen build` takes it (build.model_argument): a file's name, not the model's
    command = opts.command(context.get("model_arg", p), context["model_ts"])
    jobs = [(t.format(oosm=opts.oosm, fusion=opts.fusion), out.format(p=p), {}) for t, out in LIBRARY]
    for group, (code, doc) in context["kernel_code"].items():
        jobs.append((KERNELS[0], KERNELS[1].format(p=p, group=group), {"code": code, "group_doc": doc}))
    jobs += [(t, out.format(p=p), {}) for t, out in PROJECT]
    files: dict[str, str] = {}
    for template, out, extra in jobs:
        ctx = {**context, "banner": banner(template, p, version, command=command), **extra}
        text = env.get_template(template).render(ctx)
        files[out] = layout.lay_out(text) if out.endswith((".c", ".h")) else text
    hashes = [{"name": name, "bytes": len(text.encode()), "sha256": hashlib.sha256(text.encode()).hexdigest()}
              for name, text in files.items()]
    ctx = {**context, "banner": banner(MANIFEST[0], p, version, command=command), "file_hashes": hashes}
    files[MANIFEST[1]] = env.get_template(MANIFEST[0]).render(ctx)
    return files
