"""The node and master programs: rendered from `templates/net/` next to a generated model folder
and compiled with the host compiler. They use only the library's public API and the transport
seam (`transport.h`; `transport_udp.c` is the POSIX UDP implementation a firmware port replaces)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dfeif_codegen.check import harness

FILES = [("net/common.h.j2", "common.h"), ("net/transport.h.j2", "transport.h"),
         ("net/transport_udp.c.j2", "transport_udp.c"), ("net/node_main.c.j2", "node_main.c"),
         ("net/master_main.c.j2", "master_main.c"), ("net/relay.c.j2", "relay.c")]


@dataclass(frozen=True)
class Programs:
    folder: Path
    node: Path
    master: Path
    relay: Path        # the network emulator of `codegen network` (a host test tool)


def render_programs(model: harness.ModelDir, out: Path) -> dict[str, Path]:
    """Write the program sources for this model into `out` (file name -> path)."""
    from dfeif_codegen import __version__
    from dfeif_codegen.codegen import render

    env = render.environment(model.precision)
    out.mkdir(parents=True, exist_ok=True)
    paths = {}
    for template, name in FILES:
        text = env.get_template(template).render(
            p=model.name, P=model.name.upper(), real=f"{model.name}_real",
            banner=render.banner(template, model.name, __version__))
        paths[name] = out / name
        paths[name].write_text(text)
    return paths


def build_programs(model: harness.ModelDir, out: Path, extra: tuple[str, ...] = ()) -> Programs:
    """Render and compile node_main and master_main (library + transport + main), and the relay."""
    paths = render_programs(model, out)
    common = [*model.sources(), paths["transport_udp.c"]]
    exes = {}
    for prog in ("node", "master"):
        exes[prog] = harness.compile_program([*common, paths[f"{prog}_main.c"]], out / prog,
                                             [model.path, out], ["-std=c99", *extra])
    exes["relay"] = harness.compile_program([*model.sources(), paths["relay.c"]], out / "relay", [model.path],
                                            ["-std=c99", *extra])
    return Programs(out, exes["node"], exes["master"], exes["relay"])
