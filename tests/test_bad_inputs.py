"""Every bad input gets exit 2 (or a C error code), one line naming what and where, and leaves
every file alone (issue 11). One table across model files, scenarios, options and the C API.

Each CLI case runs in a folder holding a genuine earlier build (out/dc_motor_link), a user file
and the case's input files; the whole folder is hashed before and after and must not change."""

import ctypes
import hashlib
import os
import shutil
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

import bad_input_cases
from dfeif_codegen import cli
from dfeif_codegen.check import harness
from dfeif_codegen.codegen import build, render

MOTOR = (resources.files("dfeif_codegen") / "models" / "dc_motor_link.toml").read_text()
SQRT = (Path(__file__).parent / "data" / "sqrt_motor.toml").read_text()
SMALL = "[scenario]\nduration = 1.0\nruns = 1\nmetrics_from = 0.2\nreferences = [\"seesaw\"]\n"


def motor(old: str, new: str) -> str:
    assert old in MOTOR, old
    return MOTOR.replace(old, new, 1)


def sqrt_model(old: str, new: str) -> str:
    assert old in SQRT, old
    return SQRT.replace(old, new, 1)


NESTED = "theta = \"omega + 0.001*" + "sin(" * 20 + "theta" + ")" * 20 + "\""
NESTED14 = NESTED.replace("sin(" * 20, "sin(" * 14).replace(")" * 20, ")" * 14)  # accepted, but heavy
TOWER64 = "theta = \"omega + 1e-9*((((((((((theta+1)**64)**64)**64)**64)**64)**64)**64)**64)**64)\""

# id: (argv ({d} is the case folder), input files {name: text or bytes}, words the line must hold)
CLI = {
    # --- model files ------------------------------------------------------------------------------
    "typo angel": (["build", "{d}/in/m.toml"], {"m.toml": motor("angle = true", "angel = true")},
                   ["m.toml:", "outputs[1].angel", "unknown key"]),
    "unknown section": (["build", "{d}/in/m.toml"], {"m.toml": motor("[measurement.noise]", "[measurment]\nx = 1\n\n[measurement.noise]")},
                        ["m.toml:", "measurment", "unknown key"]),
    "unknown model key": (["build", "{d}/in/m.toml"], {"m.toml": motor("ts = 0.01", "ts = 0.01\ntss = 0.02")},
                          ["m.toml:", "model.tss", "unknown key"]),
    "unknown state key": (["build", "{d}/in/m.toml"], {"m.toml": motor('unit = "rad/s"', 'unit = "rad/s"\nnominl = 1.0')},
                          ["states[2].nominl", "unknown key"]),
    "model named string": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "string"')},
                           ["model.name", "'string'", "standard header"]),
    "model named math": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "math"')},
                         ["model.name", "'math'"]),
    "model named stdint": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "stdint"')},
                           ["model.name", "'stdint'"]),
    "model named double": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "double"')},
                           ["model.name", "'double'", "C keyword"]),
    "model named casadi": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "casadi_f0"')},
                           ["model.name", "casadi"]),
    "model name too long": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "' + "a" * 40 + '"')},
                            ["model.name", "at most 17 characters"]),
    "model name of 18 characters": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "' + "b" * 18 + '"')},
                                    ["model.name", "'" + "b" * 18 + "'", "at most 17 characters"]),
    "model name ends with _": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "dc_motor_"')},
                               ["model.name", "'dc_motor_'", "end with '_'"]),
    "model name with __": (["build", "{d}/in/m.toml"], {"m.toml": motor('name = "dc_motor_link"', 'name = "dc__motor"')},
                           ["model.name", "'dc__motor'", "contain '__'"]),
    "comment injection": (["build", "{d}/in/m.toml"],
                          {"m.toml": motor('name = "theta"\nexpr', 'name = "t */ #error x /*"\nexpr').split("# Each camera")[0]},
                          ["outputs", "t */ #error x /*", "not a usable flat output name"]),
    "parameter named int": (["build", "{d}/in/m.toml"],
                            {"m.toml": sqrt_model('name = "c"', 'name = "int"').replace("c*omega", "int*omega")},
                            ["parameters", "'int'", "not a usable parameter name"]),
    "not UTF-8": (["build", "{d}/in/m.toml"], {"m.toml": b"\xff\xfe[model]\n"}, ["m.toml", "not a UTF-8 text file"]),
    "NUL byte": (["build", "{d}/in/m.toml"], {"m.toml": MOTOR.encode() + b"\x00"}, ["m.toml", "NUL byte"]),
    "ts = inf": (["build", "{d}/in/m.toml"], {"m.toml": motor("ts = 0.01", "ts = inf")}, ["model.ts", "inf"]),
    "ts = 1e300": (["build", "{d}/in/m.toml"], {"m.toml": motor("ts = 0.01", "ts = 1e300")}, ["model.ts", "1e+300"]),
    "ts negative": (["build", "{d}/in/m.toml"], {"m.toml": motor("ts = 0.01", "ts = -0.01")}, ["model.ts", "-0.01"]),
    "mean_substeps 0": (["build", "{d}/in/m.toml"], {"m.toml": motor("ts = 0.01", "ts = 0.01\nmean_substeps = 0")},
                        ["model.mean_substeps", "whole number", "got 0"]),
    "mean_substeps 2.5": (["build", "{d}/in/m.toml"], {"m.toml": motor("ts = 0.01", "ts = 0.01\nmean_substeps = 2.5")},
                          ["model.mean_substeps", "got 2.5"]),
    "mean_substeps 65": (["build", "{d}/in/m.toml"], {"m.toml": motor("ts = 0.01", "ts = 0.01\nmean_substeps = 65")},
                         ["model.mean_substeps", "[1, 64]"]),
    "min above max": (["build", "{d}/in/m.toml"], {"m.toml": sqrt_model("min = 0.05", "min = 6.0")},
                      ["states[3]", "I: min 6 must be below max 5"]),
    "nominal outside": (["build", "{d}/in/m.toml"], {"m.toml": sqrt_model("nominal = 1.0", "nominal = 9.0")},
                        ["states[3]", "nominal 9 is outside [0.05, 5]"]),
    "min not a number": (["build", "{d}/in/m.toml"], {"m.toml": sqrt_model("min = 0.05", 'min = "low"')},
                         ["states[3].min", "finite number"]),
    "input min above max": (["build", "{d}/in/m.toml"], {"m.toml": sqrt_model("min = -24.0", "min = 30.0")},
                            ["inputs[1]", "V: min 30 must be below max 24"]),
    "power tower 64^9": (["build", "{d}/in/m.toml"], {"m.toml": motor('theta = "omega"', TOWER64)},
                         ["dynamics.f.theta", "beyond +-1024"]),
    "sin nested 20": (["build", "{d}/in/m.toml"], {"m.toml": motor('theta = "omega"', NESTED)},
                      ["dynamics.f.theta", "nested more than 16"]),
    "exponent tower": (["build", "{d}/in/m.toml"], {"m.toml": motor('theta = "omega"', 'theta = "omega + 0.01*theta**theta**theta"')},
                       ["dynamics.f.theta", "exponent tower"]),
    "acos(2) in f": (["build", "{d}/in/m.toml"], {"m.toml": motor('theta = "omega"', 'theta = "omega + acos(2)"')},
                     ["dynamics.f.theta", "acos(2)", "not a finite real"]),
    "sqrt branch undeclared": (["build", "{d}/in/m.toml"], {"m.toml": sqrt_model("min = 0.05\nmax = 5.0\n", "")},
                               ["states[3]", "several branches for I", "no declared domain"]),
    "sqrt branch domain spans 0": (["build", "{d}/in/m.toml"], {"m.toml": sqrt_model("min = 0.05", "min = -1.0").replace("nominal = 1.0", "nominal = 0.5")},
                                   ["no branch of Phi^-1 for I", "declared domain"]),
    "missing model file": (["build", "{d}/in/nowhere.toml"], {}, ["nowhere.toml", "cannot read model file"]),
    # --- build options and the output folder ------------------------------------------------------
    "--ts 1e300": (["build", "--ts", "1e300"], {}, ["--ts", "1e+300"]),
    "--ts 1e-300": (["build", "--ts", "1e-300"], {}, ["--ts", "1e-300"]),
    "--ts nan": (["build", "--ts", "nan"], {}, ["--ts", "nan"]),
    "--max-lag abc": (["build", "--max-lag", "abc"], {}, ["--max-lag", "invalid int value: 'abc'"]),
    "--max-lag 0": (["build", "--max-lag", "0"], {}, ["--max-lag", "between 1 and"]),
    "--nodes 99": (["build", "--nodes", "99"], {}, ["--nodes", "99"]),
    "--precision quad": (["build", "--precision", "quad"], {}, ["--precision", "quad"]),
    "--singular-rtol 2": (["build", "--singular-rtol", "2"], {}, ["--singular-rtol", "[0, 1)"]),
    "--max-seconds 0": (["build", "--max-seconds", "0"], {}, ["--max-seconds", "positive"]),
    "time budget": (["build", "--max-seconds", "0.001"], {}, ["stopped after 0.001 CPU-s while", "--max-seconds"]),
    # a generous clock, so that on a loaded machine the memory budget, not the time budget, stops it
    "memory budget": (["build", "{d}/in/m.toml", "--max-memory", "0.001", "--max-seconds", "600"],
                      {"m.toml": motor('theta = "omega"', NESTED14)},
                      ["m.toml", "memory budget", "--max-memory"]),
    "--out is a file": (["build", "--out", "{d}/user/notes.txt"], {}, ["--out", "notes.txt", "not a folder"]),
    "user file in module folder": (["build"], {"@out/dc_motor_link/my_notes.c": "int mine;\n"},
                                   ["dc_motor_link/my_notes.c", "not written by codegen build", "--force"]),
    "user file named like the model": (["build"], {"@out/dc_motor_link": "my file\n"},
                                       ["out/dc_motor_link", "did not write", "--force"]),
    "--inspect --ts 1e300": (["inspect", "--ts", "1e300"], {}, ["--ts", "1e+300"]),
    # --- scenarios and simulate/verify options ----------------------------------------------------
    "scenario not UTF-8": (["simulate", "--scenario", "{d}/in/s.toml"], {"s.toml": b"\xff\xfe\x00"},
                           ["s.toml", "not a UTF-8 text file"]),
    "scenario duration 1e9": (["simulate", "--scenario", "{d}/in/s.toml"], {"s.toml": SMALL.replace("1.0", "1e9", 1)},
                              ["s.toml:", "scenario.duration", "at most"]),
    "delay beyond window": (["simulate", "--scenario", "{d}/in/s.toml"], {"s.toml": SMALL + "[[grid]]\nd = [40, 40]\np = 0.5\n"},
                            ["s.toml:", "grid[1].d", "delay 40", "--max-lag 32"]),
    "uplink delay beyond window": (["simulate", "--scenario", "{d}/in/s.toml", "--max-lag", "8"],
                                   {"s.toml": SMALL + "[uplink]\nd = 9\np = 0.5\n"}, ["uplink.d", "delay 9", "--max-lag 8"]),
    "network delay beyond window": (["network", "--max-lag", "4"], {}, ["paper.toml", "grid[3].d", "delay 8", "--max-lag 4"]),
    "scenario 17 nodes": (["simulate", "--scenario", "{d}/in/s.toml"], {"s.toml": SMALL + "[[nodes]]\n" * 17},
                          ["s.toml:", "nodes", "1 to 16", "got 17"]),
    "verify scenario 17 nodes": (["verify", "--scenario", "{d}/in/s.toml"], {"s.toml": SMALL + "[[nodes]]\n" * 17},
                                 ["s.toml:", "nodes", "1 to 16", "got 17"]),
    "unknown scenario key": (["simulate", "--scenario", "{d}/in/s.toml"], {"s.toml": SMALL + "colour = 2\n"},
                             ["s.toml:", "scenario.colour", "unknown field"]),
    "--json unwritable": (["simulate", "--scenario", "{d}/in/s.toml", "--json", "{d}/user/notes.txt/r.json"],
                          {"s.toml": SMALL}, ["--json", "r.json", "not a writable folder"]),
    "--plot is a file": (["simulate", "--scenario", "{d}/in/s.toml", "--plot", "{d}/user/notes.txt"],
                         {"s.toml": SMALL}, ["--plot", "notes.txt", "not a folder"]),
    "--plot without matplotlib": (["simulate", "--scenario", "{d}/in/s.toml", "--plot", "{d}/figs"],
                                  {"s.toml": SMALL, "!no-matplotlib": ""}, ["--plot needs matplotlib"]),
    "--runs 0": (["simulate", "--scenario", "{d}/in/s.toml", "--runs", "0"], {"s.toml": SMALL}, ["--runs", "needs 1 to"]),
    "reference outside domain": (["simulate", "{d}/in/q.toml", "--scenario", "{d}/in/s.toml"],
                                 {"q.toml": SQRT, "s.toml": SMALL.replace("seesaw", "sinusoid").replace("1.0", "4.0", 1)},
                                 ["s.toml", "reference", "Phi^-1 is undefined", "I = sqrt", "t = "]),
    "verify scenario not UTF-8": (["verify", "--scenario", "{d}/in/s.toml"], {"s.toml": b"\xff"}, ["s.toml", "UTF-8"]),
    "bench --repeat 0": (["bench", "--repeat", "0"], {}, ["--repeat", "between 1 and 1000"]),
    "bench --out unwritable": (["bench", "--out", "{d}/user/notes.txt/B.md"], {}, ["--out", "B.md", "not a writable folder"]),
}


def tree(folder: Path) -> dict[str, str]:
    """Path -> sha256 of every file and symlink below folder (folders by their listing)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_symlink():
            out[rel] = "link:" + str(p.readlink())
        elif p.is_file():
            out[rel] = hashlib.sha256(p.read_bytes()).hexdigest()
        else:
            out[rel] = "dir"
    return out


@pytest.fixture(scope="module")
def earlier_build(tmp_path_factory):
    """A genuine earlier build of the default model: what a user's tree holds before a bad call."""
    root = tmp_path_factory.mktemp("earlier")
    build.build("dc_motor_link", root / "out")
    return root / "out"


def run_cli(argv, capsys) -> tuple[int, list[str]]:
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.err.strip().splitlines()


def _class(argv: list[str]) -> str:
    """The class of a hand-written case (the generated ones carry theirs)."""
    if any(a.endswith((".toml",)) and "/in/m.toml" in a or a.endswith("nowhere.toml") for a in argv):
        return "model file"
    if any(a.startswith("--scenario") for a in argv) and any("/in/s.toml" in a for a in argv) and len(argv) <= 3:
        return "scenario file"
    if any(a in ("--out", "--json", "--plot", "--csv", "--results", "--keep") for a in argv) or argv == ["build"]:
        return "output path"
    if any(a in ("--max-seconds", "--max-memory") for a in argv):
        return "time and memory budget"
    return "option: out of range"


ALL = {case: (_class(argv), argv, files, words) for case, (argv, files, words) in CLI.items()}
ALL.update(bad_input_cases.generated())


@pytest.mark.parametrize("case", list(ALL))
def test_bad_cli_input(case, tmp_path, earlier_build, capsys, monkeypatch):
    _, argv, files, words = ALL[case]
    if isinstance(files.get("m.toml"), tuple):                 # a model file under another name
        files = {**files, "m.toml": motor('name = "dc_motor_link"', f'name = "{files["m.toml"][1]}"')}
    shutil.copytree(earlier_build, tmp_path / "out")
    (tmp_path / "user").mkdir()
    (tmp_path / "user" / "notes.txt").write_text("the user's own notes\n")
    (tmp_path / "in").mkdir()
    for name, content in files.items():
        if name == "!no-matplotlib":
            monkeypatch.setitem(sys.modules, "matplotlib", None)
            continue
        path = tmp_path / name[1:] if name.startswith("@") else tmp_path / "in" / name
        if path.is_dir():
            shutil.rmtree(path)
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
    monkeypatch.chdir(tmp_path)
    argv = [a.replace("{d}", str(tmp_path)) for a in argv]
    if argv[0] == "build" and "--out" not in argv:
        argv += ["--out", str(tmp_path / "out")]
    before = tree(tmp_path)
    code, lines = run_cli(argv, capsys)
    assert code == 2, (code, lines)
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"codegen {argv[0]}: error:") and "Traceback" not in lines[0], lines[0]
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert tree(tmp_path) == before, "a bad input changed files"


def test_failed_compile_check_keeps_the_earlier_build(tmp_path, earlier_build, capsys, monkeypatch):
    """A build whose C does not compile exits 2 and leaves the earlier build as it was."""
    shutil.copytree(earlier_build, tmp_path / "out")
    original = render._load

    def broken(name):
        text, path, uptodate = original(name)
        return (text + "\nint broken(void) { return casadi_nan; }\n" if name == "control.c.j2" else text), path, uptodate
    monkeypatch.setattr(render, "_load", broken)
    before = tree(tmp_path)
    code, lines = run_cli(["build", "--out", str(tmp_path / "out")], capsys)
    assert code == 2 and len(lines) == 1
    assert "does not compile" in lines[0] and "casadi_nan" in lines[0] and "dc_motor_link_control.c" in lines[0]
    assert tree(tmp_path) == before


def test_force_replaces_only_when_asked(tmp_path, earlier_build, capsys):
    shutil.copytree(earlier_build, tmp_path / "out")
    (tmp_path / "out" / "dc_motor_link" / "mine.txt").write_text("x")
    assert run_cli(["build", "--out", str(tmp_path / "out")], capsys)[0] == 2
    assert (tmp_path / "out" / "dc_motor_link" / "mine.txt").exists()
    (tmp_path / "out" / "dc_motor_link" / "dc_motor_link.h").write_text("edited by hand")
    assert run_cli(["build", "--out", str(tmp_path / "out"), "--force"], capsys)[0] == 0
    # --force replaces the build's files and keeps the user's (it deleted them before)
    assert (tmp_path / "out" / "dc_motor_link" / "mine.txt").read_text() == "x"
    (tmp_path / "out" / "dc_motor_link" / "mine.txt").unlink()
    assert tree(tmp_path / "out") == tree(earlier_build)  # deterministic: the same build again


# --- the C API ----------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def clib(earlier_build, tmp_path_factory, host_cc):
    folder = earlier_build / "dc_motor_link"
    so = tmp_path_factory.mktemp("clib") / "libmotor.so"
    harness.compile_shared([p for p in sorted(folder.glob("*.c")) if p.name != "example_main.c"], so, [folder])
    lib = harness.load(so)
    for f in ("node_size", "master_size"):
        getattr(lib, f"dc_motor_link_{f}").restype = ctypes.c_size_t
    return lib


def ptr(a):
    return None if a is None else a.ctypes.data_as(ctypes.c_void_p)


N, M, NODES = 3, 1, 2
P_GOOD = np.eye(N) * 0.01
ERR_ARG, ERR_NONFINITE, ERR_SINGULAR = -1, -3, -4


def fresh(lib, kind):
    """An initialised node or master struct (bytes) to call into."""
    buf = ctypes.create_string_buffer(getattr(lib, f"dc_motor_link_{kind}_size")())
    x0, q, R = np.zeros(N), np.ones(M), np.eye(M) * 1e-6
    if kind == "node":
        assert lib.dc_motor_link_node_init(buf, ptr(x0), ptr(P_GOOD), ptr(R), ptr(q)) == 0
    else:
        assert lib.dc_motor_link_master_init(buf, ptr(x0), ptr(P_GOOD), ptr(q)) == 0
    return buf


def p0(kind):
    P = P_GOOD.copy()
    if kind == "asymmetric":
        P[0, 1] = 1e-3
    elif kind == "indefinite":
        P[2, 2] = -0.01
    elif kind == "singular":
        P[1, 1] = 0.0
    elif kind == "nan":
        P[0, 0] = np.nan
    return P


C_CASES = {
    # id: (struct kind, call(lib, struct) -> return code, expected code)
    "node_init asymmetric P0": ("node", lambda lib, s: lib.dc_motor_link_node_init(
        s, ptr(np.zeros(N)), ptr(p0("asymmetric")), ptr(np.eye(M) * 1e-6), ptr(np.ones(M))), ERR_ARG),
    "node_init indefinite P0": ("node", lambda lib, s: lib.dc_motor_link_node_init(
        s, ptr(np.zeros(N)), ptr(p0("indefinite")), ptr(np.eye(M) * 1e-6), ptr(np.ones(M))), ERR_ARG),
    "node_init singular P0": ("node", lambda lib, s: lib.dc_motor_link_node_init(
        s, ptr(np.zeros(N)), ptr(p0("singular")), ptr(np.eye(M) * 1e-6), ptr(np.ones(M))), ERR_ARG),
    "master_init asymmetric P0": ("master", lambda lib, s: lib.dc_motor_link_master_init(
        s, ptr(np.zeros(N)), ptr(p0("asymmetric")), ptr(np.ones(M))), ERR_ARG),
    "master_init indefinite P0": ("master", lambda lib, s: lib.dc_motor_link_master_init(
        s, ptr(np.zeros(N)), ptr(p0("indefinite")), ptr(np.ones(M))), ERR_ARG),
    "master_init NaN P0": ("master", lambda lib, s: lib.dc_motor_link_master_init(
        s, ptr(np.zeros(N)), ptr(p0("nan")), ptr(np.ones(M))), ERR_NONFINITE),
    "node_update gamma 2": ("node", lambda lib, s: lib.dc_motor_link_node_update(s, ptr(np.zeros(M)), 2), ERR_ARG),
    "node_update z NULL": ("node", lambda lib, s: lib.dc_motor_link_node_update(s, None, 1), ERR_ARG),
    "node_init q negative": ("node", lambda lib, s: lib.dc_motor_link_node_init(
        s, ptr(np.zeros(N)), ptr(P_GOOD), ptr(np.eye(M) * 1e-6), ptr(-np.ones(M))), ERR_ARG),
    "node_init R not positive": ("node", lambda lib, s: lib.dc_motor_link_node_init(
        s, ptr(np.zeros(N)), ptr(P_GOOD), ptr(-np.eye(M)), ptr(np.ones(M))), ERR_SINGULAR),
    "master_init q negative": ("master", lambda lib, s: lib.dc_motor_link_master_init(
        s, ptr(np.zeros(N)), ptr(P_GOOD), ptr(-np.ones(M))), ERR_ARG),
    "master_predict NaN v": ("master", lambda lib, s: lib.dc_motor_link_master_predict(
        s, ptr(np.full(M, np.nan))), ERR_NONFINITE),
    "gains lambda -5": ("node", lambda lib, s: lib.dc_motor_link_gains(ptr(np.array([-5.0])), ptr(np.zeros(N))),
                        ERR_ARG),
    "gains lambda 0": ("node", lambda lib, s: lib.dc_motor_link_gains(ptr(np.array([0.0])), ptr(np.zeros(N))),
                       ERR_ARG),
}


@pytest.mark.parametrize("case", list(C_CASES))
def test_bad_c_call_is_refused_and_changes_nothing(case, clib):
    kind, call, expected = C_CASES[case]
    struct = fresh(clib, kind)
    before = bytes(struct)
    assert call(clib, struct) == expected
    assert bytes(struct) == before


def test_master_fuse_refuses_present_not_0_or_1(clib):
    node, master = fresh(clib, "node"), fresh(clib, "master")
    packet_size = clib.dc_motor_link_packet_size
    packet_size.restype = ctypes.c_size_t
    packets = ctypes.create_string_buffer(packet_size() * NODES)
    for i in range(NODES):
        assert clib.dc_motor_link_node_packet(node, ctypes.byref(packets, i * packet_size())) == 0
    before = bytes(master)
    for bad in (2, 255):
        present = np.array([1, bad], dtype=np.uint8)
        assert clib.dc_motor_link_master_fuse(master, packets, ptr(present)) == ERR_ARG
        assert bytes(master) == before
    assert clib.dc_motor_link_master_fuse(master, packets, ptr(np.array([1, 1], dtype=np.uint8))) == 0


def test_master_fuse_called_again_adds_the_packets_not_yet_fused(clib):
    """The difference rule (this build's) adds information: node 0's packet, then both (node
    1's arrived), is the fusion of both in one call to rounding (the independent expectation:
    one call), far from either node alone; the same call again leaves the estimate as it was."""
    packet_size = clib.dc_motor_link_packet_size
    packet_size.restype = ctypes.c_size_t
    packets = ctypes.create_string_buffer(packet_size() * NODES)
    for i, z in enumerate((0.01, -0.02)):
        node = fresh(clib, "node")
        assert clib.dc_motor_link_node_update(node, ptr(np.array([z])), 1) == 0
        assert clib.dc_motor_link_node_packet(node, ctypes.byref(packets, i * packet_size())) == 0

    def fused(*calls):
        master = fresh(clib, "master")
        for present in calls:
            assert clib.dc_motor_link_master_fuse(master, packets, ptr(np.array(present, dtype=np.uint8))) == 0
        x, P = np.zeros(N), np.zeros((N, N))
        assert clib.dc_motor_link_master_estimate(master, ptr(x), ptr(P)) == 0
        return x, P

    x2, P2 = fused([1, 1])
    again = fused([1, 1], [1, 1])   # both packets ignored (counted): the estimate bit for bit
    assert np.array_equal(again[0], x2) and np.array_equal(again[1], P2)
    for calls in (([1, 0], [1, 1]), ([0, 1], [1, 0])):
        x, P = fused(*calls)
        # two 3x3 information sums associated differently: a few ulps times cond(P) < 1e3
        assert np.allclose(x, x2, rtol=1e-12, atol=1e-15) and np.allclose(P, P2, rtol=1e-12, atol=1e-18)
    for alone in ([1, 0], [0, 1]):
        assert abs(fused(alone)[1][0, 0] - P2[0, 0]) > 0.2 * P2[0, 0]


def test_gains_overflow_is_nonfinite_and_leaves_output(clib):
    gains = np.full(N, 7.0)
    # k_3 = lambda^3 = 1e600 overflows a double: ERR_NONFINITE, gains untouched
    assert clib.dc_motor_link_gains(ptr(np.array([1e200])), ptr(gains)) == ERR_NONFINITE
    assert np.all(gains == 7.0)
    assert clib.dc_motor_link_gains(ptr(np.array([np.inf])), ptr(gains)) == ERR_NONFINITE
    assert clib.dc_motor_link_gains(ptr(np.array([2.0])), ptr(gains)) == 0 and list(gains) == [6.0, 12.0, 8.0]


def test_control_near_singular_parameters(clib):
    """k_e shrunk 1e7-fold makes |G| = k_e/(J L) 1e-7 of nominal: ERR_SINGULAR, u and v untouched."""
    params = np.array([0.005, 2.0, 0.5e-7, 0.05, 0.02, 0.3, 9.81, 0.25])
    x, flags, gains = np.zeros(N), np.zeros(N + M), np.ones(N)
    u, v = np.full(M, 42.0), np.full(M, 42.0)
    assert clib.dc_motor_link_control(ptr(x), ptr(flags), ptr(gains), ptr(params), ptr(u), ptr(v), None) == ERR_SINGULAR
    assert u[0] == 42.0 and v[0] == 42.0
    params[2] = 0.5e-5   # 1e-5 of nominal: above the default 1e-6, accepted
    assert clib.dc_motor_link_control(ptr(x), ptr(flags), ptr(gains), ptr(params), ptr(u), ptr(v), None) == 0


def table_markdown() -> str:
    """docs/bad_inputs.md: every class of bad input, how many cases the tests hold and what each
    gets, then every case (written by this file: DFEIF_WRITE_DOCS=1 pytest tests/test_bad_inputs.py)."""
    classes: dict[str, list] = {}
    for case, (cls, argv, _, words) in ALL.items():
        classes.setdefault(cls, []).append((case, argv, words))
    lines = ["# Bad input: what each class gets", "",
             "Written by `tests/test_bad_inputs.py` from the cases it runs (regenerate with",
             "`DFEIF_WRITE_DOCS=1 python -m pytest tests/test_bad_inputs.py -k docs`). Every command-line",
             "case exits with code 2 before any long work, prints exactly one line `codegen COMMAND: error:",
             "...` on stderr naming what is wrong and where (the words listed must be in it), and leaves",
             "every file of its folder as it was (an earlier build, a user file, its inputs: hashed before",
             "and after). Every C case returns the code listed and leaves the struct bit for bit as it was.",
             f"{len(ALL)} command-line cases and {len(C_CASES) + 3} C cases.", "",
             "| class | cases | example | exit | the line names |", "|---|---:|---|---:|---|"]
    for cls, cases in sorted(classes.items()):
        case, argv, words = cases[0]
        lines.append(f"| {cls} | {len(cases)} | `codegen {' '.join(argv)}` | 2 | {', '.join(words)} |")
    lines.append(f"| C API: bad argument or covariance | {len(C_CASES) + 3} | `node_init` with an asymmetric P0 "
                 "| ERR_ARG / ERR_NONFINITE / ERR_SINGULAR | struct unchanged |")
    lines += ["", "## Every case", "", "| case | class | command | the line names |", "|---|---|---|---|"]
    for case, (cls, argv, _, words) in ALL.items():
        cmd = " ".join(a.replace("|", "\\|") for a in argv)
        lines.append(f"| {case.replace('|', '/')} | {cls} | `codegen {cmd}` | {', '.join(words).replace('|', '/')} |")
    for case, (_, _, expected) in C_CASES.items():
        lines.append(f"| {case} | C API | (ctypes) | returns {expected} |")
    return "\n".join(lines) + "\n"


def test_docs_table_is_current():
    doc = Path(__file__).resolve().parents[1] / "docs" / "bad_inputs.md"
    if os.environ.get("DFEIF_WRITE_DOCS"):
        doc.write_text(table_markdown())
    assert doc.read_text() == table_markdown(), "docs/bad_inputs.md is stale: rerun with DFEIF_WRITE_DOCS=1"
    readme = (doc.parents[1] / "README.md").read_text()
    c_cases = len(C_CASES) + 3
    assert (f"from the {len(ALL) + c_cases} cases it runs: {len(ALL)} on the command line, {c_cases} C calls"
            in " ".join(readme.split())), "README.md's count of bad-input cases is stale"


def test_the_table_is_big_enough():
    assert len(ALL) + len(C_CASES) >= 250


def test_every_option_has_help_with_its_default():
    """`codegen CMD --help` says what every option does and, where it has one, its default."""
    import argparse

    sub = next(a for a in cli.parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = [f"{name} {a.option_strings[0]}" for name, sp in sub.choices.items() for a in sp._actions
               if a.option_strings and a.dest != "help" and (not a.help or (
                   a.default not in (None, False, argparse.SUPPRESS) and "default" not in a.help))]
    assert missing == []
