"""`codegen build`: the committed generated/ equals a fresh build, rebuilds are byte-identical, a
failed build leaves the previous output untouched, bad options are one line and exit 2, and every
file carries its banner. Also the sympy -> CasADi converter and the renderer's strictness."""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import jinja2
import pytest

from dfeif_codegen import cli
from dfeif_codegen.codegen import build, output, provenance, render
from dfeif_codegen.codegen.kernels import csource
from dfeif_codegen.codegen.options import Options
from dfeif_codegen.symbolic import model

ROOT = Path(__file__).resolve().parents[1]
MODELS = model.builtin_names()   # every built-in model: generated/ holds each one


def cli_run(*argv: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "dfeif_codegen.cli", *argv], capture_output=True, text=True,
                          timeout=300, env={**os.environ, **(env or {})}, cwd=ROOT)


def tree(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """Every built-in model built with default options through the CLI."""
    out = tmp_path_factory.mktemp("fresh")
    for name in MODELS:
        result = cli_run("build", name, "--out", str(out))
        assert result.returncode == 0, result.stderr
    return out


@pytest.mark.parametrize("name", MODELS)
def test_committed_generated_equals_fresh_build(fresh, name):
    committed = ROOT / "generated" / name
    assert committed.is_dir(), "generated/ is missing: run `codegen build` for each built-in model"
    assert tree(committed) == tree(fresh / name), (
        f"generated/{name} is stale: rerun `codegen build {name}` and commit the result")


def test_rebuild_is_byte_identical(fresh, tmp_path):
    result = cli_run("build", "--out", str(tmp_path), env={"PYTHONHASHSEED": "12345"})
    assert result.returncode == 0, result.stderr
    assert tree(tmp_path / "dc_motor_link") == tree(fresh / "dc_motor_link")


def test_output_has_no_timestamps_or_paths(fresh):
    for name in MODELS:
        for fname, data in tree(fresh / name).items():
            text = data.decode()
            assert str(fresh) not in text and str(ROOT) not in text and "/home/" not in text, fname
            assert not re.search(r"\b20\d\d-\d\d-\d\d\b|\d\d:\d\d:\d\d", text), fname


def test_every_file_has_banner_and_manifest_hashes(fresh):
    folder = fresh / "dc_motor_link"
    files = tree(folder)
    for fname, data in files.items():
        first = data.decode().splitlines()[0 if not fname.endswith(".json") else 1]
        assert "DO NOT EDIT" in first and "dc_motor_link" in first and ".j2" in first, fname
    manifest = json.loads(files["manifest.json"])
    assert manifest["model"] == "dc_motor_link" and len(manifest["model_hash"]) == 64
    assert manifest["options"] == {"ts": 0.01, "max_lag": 32, "nodes": 2, "oosm": "replay",
                                   "fusion": "difference", "precision": "double", "singular_rtol": 1e-6,
                                   "predictor": "held", "disturbance": None, "tau": None, "gate": None}
    assert "dependencies" not in manifest and manifest["tool"] == {"name": "dfeif-codegen", "version": "0.1.0"}
    assert set(manifest["files"]) == set(files) - {"manifest.json"}
    for fname, entry in manifest["files"].items():
        assert entry["sha256"] == hashlib.sha256(files[fname]).hexdigest()


def test_dependency_patch_releases_change_nothing(fresh, tmp_path, monkeypatch):
    """The output records no numpy, sympy or jinja2 version and only CasADi's major.minor: a build
    under other patch releases is byte-identical to the one under the installed ones."""
    from importlib import metadata

    real = metadata.version
    bumped = {"numpy": "9.9.9", "sympy": "9.9.9", "jinja2": "9.9.9",
              "casadi": ".".join(real("casadi").split(".")[:2]) + ".99"}
    monkeypatch.setattr(provenance.metadata, "version", lambda dist: bumped.get(dist) or real(dist))
    build.build("dc_motor_link", tmp_path)
    assert tree(tmp_path / "dc_motor_link") == tree(fresh / "dc_motor_link")
    for data in tree(fresh / "dc_motor_link").values():
        for dist in ("numpy", "sympy", "jinja2", "casadi"):
            assert real(dist).encode() not in data or real(dist).count(".") < 2, dist


def test_build_check_reports_up_to_date_stale_and_missing(fresh, tmp_path):
    shutil.copytree(fresh / "dc_motor_link", tmp_path / "dc_motor_link")
    ok = cli_run("build", "--check", "--out", str(tmp_path))
    assert ok.returncode == 0 and "up to date" in ok.stdout, ok.stderr
    before = tree(tmp_path / "dc_motor_link")
    with open(tmp_path / "dc_motor_link" / "dc_motor_link.mk", "a") as f:
        f.write("# edited\n")
    (tmp_path / "dc_motor_link" / "notes.txt").write_text("mine")
    (tmp_path / "dc_motor_link" / "example_main.c").unlink()
    stale = cli_run("build", "--check", "--out", str(tmp_path))
    assert stale.returncode == 1 and stale.stdout == ""
    line, = stale.stderr.splitlines()
    assert "dc_motor_link.mk, missing: example_main.c, extra: notes.txt" in line and "Traceback" not in line
    assert tree(tmp_path / "dc_motor_link") != before and (tmp_path / "dc_motor_link" / "notes.txt").is_file()
    # another option than the one built with is stale too (the check uses the options given)
    shutil.rmtree(tmp_path / "dc_motor_link")
    shutil.copytree(fresh / "dc_motor_link", tmp_path / "dc_motor_link")
    assert cli_run("build", "--check", "--out", str(tmp_path), "--max-lag", "8").returncode == 1
    missing = cli_run("build", "two_link_arm", "--check", "--out", str(tmp_path))
    assert missing.returncode == 2 and "two_link_arm: missing" in missing.stderr
    assert not (tmp_path / "two_link_arm").exists()


def test_header_defines_and_options(tmp_path):
    result = cli_run("build", "--out", str(tmp_path), "--precision", "float", "--max-lag", "7", "--nodes", "3",
                     "--oosm", "retrodict", "--fusion", "ci", "--ts", "0.005")
    assert result.returncode == 0, result.stderr
    header = (tmp_path / "dc_motor_link" / "dc_motor_link.h").read_text()
    for define in ("DC_MOTOR_LINK_NX 3", "DC_MOTOR_LINK_NY 1", "DC_MOTOR_LINK_NP 8", "DC_MOTOR_LINK_NMAX 7",
                   "DC_MOTOR_LINK_NNODES 3", "DC_MOTOR_LINK_TS 0.005f", "DC_MOTOR_LINK_OOSM_RETRODICT 1",
                   "DC_MOTOR_LINK_FUSION_CI 1", "typedef float dc_motor_link_real"):
        assert re.search(r"(#define |)" + re.escape(define), header), define
    control = (tmp_path / "dc_motor_link" / "dc_motor_link_control.c").read_text()
    assert "const real dc_motor_link_ts = DC_MOTOR_LINK_TS;" in control
    assert "dc_motor_link_kern_retro_step" in (tmp_path / "dc_motor_link" / "dc_motor_link_kernels.h").read_text()


def test_banner_command_regenerates_the_same_build(tmp_path):
    """A build with non-default options names them in every file's banner; running that command
    (a second build, the oracle) gives the same files byte for byte."""
    argv = ["--precision", "float", "--max-lag", "7", "--oosm", "retrodict", "--fusion", "ci", "--ts", "0.005"]
    assert cli_run("build", "--out", str(tmp_path / "a"), *argv).returncode == 0
    first = tree(tmp_path / "a" / "dc_motor_link")
    text = " ".join(first["dc_motor_link.h"].decode().split("*/")[0].replace("*", " ").split())
    command = re.search(r"regenerate with `codegen build ([^`]*)`", text).group(1).split()
    assert command[0] == "dc_motor_link" and set(argv) <= set(command)
    assert cli_run("build", *command, "--out", str(tmp_path / "b")).returncode == 0
    assert tree(tmp_path / "b" / "dc_motor_link") == first
    default = tree(ROOT / "generated" / "dc_motor_link")["dc_motor_link.h"].decode()
    assert "regenerate with `codegen build dc_motor_link`" in default      # the default build: no flags


def test_cli_prints_files_sizes_and_sizeof(tmp_path):
    result = cli_run("build", "--out", str(tmp_path))
    assert result.returncode == 0
    out = result.stdout
    assert "dc_motor_link_node.c" in out and "bytes" in out
    if build.host_compiler():
        node = int(re.search(r"sizeof: node (\d+) B", out).group(1))
        assert node <= 4096, "node state over the 4 KiB budget at N_max = 32 (double)"
        readme = (ROOT / "README.md").read_text()
        said = re.search(r"dc_motor_link_node node; +/\* one per camera; (\d+) B in double", readme)
        assert said and int(said.group(1)) == node, "README's example states the node's size: update it"
    else:
        assert "sizeof: skipped" in out


@pytest.mark.parametrize("argv, fragment", [
    (["--max-lag", "0"], "--max-lag"),
    (["--nodes", "0"], "--nodes"),
    (["--ts", "-1"], "--ts"),
    (["--ts", "nan"], "--ts"),
    (["no_such_model"], "not a built-in model"),
])
def test_bad_input_is_one_line_exit_2_and_keeps_old_output(tmp_path, argv, fragment):
    assert cli_run("build", "--out", str(tmp_path)).returncode == 0
    before = tree(tmp_path)
    result = cli_run("build", "--out", str(tmp_path), *argv)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and lines[0].startswith("codegen build: error:")
    assert tree(tmp_path) == before


def test_failure_while_writing_leaves_old_output(tmp_path, monkeypatch):
    files = {"a.h": "old a\n", "b.c": "old b\n", "manifest.json": '{"files": {"a.h": {}, "b.c": {}}}'}
    output.write_atomic(tmp_path, "m", files)
    calls = {"n": 0}
    real_write = Path.write_bytes

    def flaky(self, data):
        calls["n"] += 1
        if calls["n"] == 2:
            raise OSError(28, "No space left on device")
        return real_write(self, data)
    monkeypatch.setattr(Path, "write_bytes", flaky)
    with pytest.raises(build.BuildError, match="No space left"):
        output.write_atomic(tmp_path, "m", {"a.h": "new a\n", "b.c": "new b\n", "c.c": "new c\n",
                                           "manifest.json": "{}"})
    monkeypatch.undo()
    assert tree(tmp_path / "m") == {k: v.encode() for k, v in files.items()}
    assert [p.name for p in tmp_path.iterdir()] == ["m"], "temporary folder left behind"


def test_template_error_is_one_line_and_keeps_old_output(tmp_path, monkeypatch):
    assert cli.main(["build", "--out", str(tmp_path)]) == 0
    before = tree(tmp_path)
    original = render._load

    def broken(name):
        text, path, uptodate = original(name)
        return (text + "{{ no_such_variable }}" if name == "node.c.j2" else text), path, uptodate
    monkeypatch.setattr(render, "_load", broken)
    with pytest.raises(build.BuildError, match="template error: UndefinedError"):
        build.generate(model.load("dc_motor_link"), Options(ts=0.01))
    assert cli.main(["build", "--out", str(tmp_path)]) == 2
    assert tree(tmp_path) == before


def test_replaces_its_own_stale_files_but_not_the_users(tmp_path):
    """A file an earlier build wrote (listed in its manifest) and this one does not is removed;
    a file the user put there stops the build (exit 2) unless --force."""
    assert cli_run("build", "--out", str(tmp_path)).returncode == 0
    folder = tmp_path / "dc_motor_link"
    manifest = json.loads((folder / "manifest.json").read_text())
    manifest["files"]["stale.c"] = {"bytes": 4, "sha256": hashlib.sha256(b"old\n").hexdigest()}
    (folder / "manifest.json").write_text(json.dumps(manifest))
    (folder / "stale.c").write_text("old\n")
    assert cli_run("build", "--out", str(tmp_path)).returncode == 0
    assert not (folder / "stale.c").exists()
    (folder / "mine.c").write_text("mine\n")
    result = cli_run("build", "--out", str(tmp_path))
    assert result.returncode == 2 and "mine.c" in result.stderr and (folder / "mine.c").read_text() == "mine\n"


def test_a_hand_edited_file_is_not_replaced_without_force(tmp_path):
    """A generated file changed since the build wrote it (sha256 unlike the manifest's) stops the
    next build (exit 2, the file named and kept); one whose lines a checkout turned into CRLF is
    not an edit; --force replaces the edit with the generated text."""
    assert cli_run("build", "--out", str(tmp_path)).returncode == 0
    node = tmp_path / "dc_motor_link" / "dc_motor_link_node.c"
    generated = node.read_bytes()
    node.write_bytes(generated.replace(b"\n", b"\r\n"))
    assert cli_run("build", "--out", str(tmp_path), "--check").returncode == 0      # up to date, as checked out
    assert cli_run("build", "--out", str(tmp_path)).returncode == 0
    assert node.read_bytes() == generated
    node.write_bytes(generated + b"/* my fix */\n")
    check = cli_run("build", "--out", str(tmp_path), "--check")
    assert check.returncode == 1 and "dc_motor_link_node.c" in check.stderr
    result = cli_run("build", "--out", str(tmp_path))
    assert result.returncode == 2 and "dc_motor_link_node.c" in result.stderr and "changed since" in result.stderr
    assert result.stderr.count("\n") == 1 and node.read_bytes().endswith(b"/* my fix */\n")
    assert cli_run("build", "--out", str(tmp_path), "--force").returncode == 0
    assert node.read_bytes() == generated
    (tmp_path / "dc_motor_link" / "manifest.json").write_text("{")
    result = cli_run("build", "--out", str(tmp_path))
    assert result.returncode == 2 and "manifest.json" in result.stderr and "unreadable JSON" in result.stderr
    assert node.read_bytes() == generated


def test_strict_undefined():
    env = render.environment()
    with pytest.raises(jinja2.UndefinedError):
        env.from_string("{{ missing }}").render()
    assert render.literal("float")(0.01) == "0.01f" and render.literal("double")(2) == "2.0"


@pytest.mark.skipif(shutil.which("make") is None or shutil.which("cc") is None, reason="make or cc missing")
def test_make_fragment_builds_the_example(fresh, tmp_path):
    gen = fresh / "dc_motor_link"
    (tmp_path / "Makefile").write_text(
        f"include {gen}/dc_motor_link.mk\n"
        "app: $(DC_MOTOR_LINK_SRCS) $(DC_MOTOR_LINK_DIR)/example_main.c\n"
        "\t$(CC) -std=c99 $(DC_MOTOR_LINK_CFLAGS) $^ $(DC_MOTOR_LINK_LDLIBS) -o $@\n")
    result = subprocess.run(["make", "-s", "app"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert subprocess.run([str(tmp_path / "app")], capture_output=True, timeout=60).returncode == 0


@pytest.mark.skipif(shutil.which("make") is None or shutil.which("cc") is None, reason="make or cc missing")
def test_make_fragments_object_rule_keeps_the_generated_folder_clean(tmp_path):
    """The .mk's suggested rule, uncommented as it says, builds the library's objects with its
    size flags into the user's OBJDIR: the generated folder gains no file, so the next build may
    replace it (it refused when the old advice put the .o files beside the sources)."""
    module = build.build("dc_motor_link", tmp_path / "gen")
    lines = (module.path / "dc_motor_link.mk").read_text().splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.endswith("Uncommented, with OBJDIR set:")) + 1
    end = next(i for i in range(start, len(lines)) if not lines[i].startswith("#     "))
    rule = "\n".join(ln[len("#     "):] for ln in lines[start:end])
    (tmp_path / "Makefile").write_text(
        f"OBJDIR := obj\nCFLAGS := -std=c99 -O2\ninclude {module.path}/dc_motor_link.mk\n{rule}\n"
        "app: $(DC_MOTOR_LINK_OBJS) $(DC_MOTOR_LINK_DIR)/example_main.c\n"
        "\t$(CC) $(CFLAGS) $(DC_MOTOR_LINK_CFLAGS) $^ $(DC_MOTOR_LINK_LDLIBS) -o $@\n")
    before = sorted(p.name for p in module.path.iterdir())
    result = subprocess.run(["make", "app"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "-ffunction-sections -fdata-sections -fno-math-errno -c" in result.stdout
    assert sorted(p.name for p in (tmp_path / "obj").iterdir()) == sorted(
        f[:-2] + ".o" for f in module.files if f.endswith(".c") and f != "example_main.c")
    assert sorted(p.name for p in module.path.iterdir()) == before
    output.check_target(tmp_path / "gen", "dc_motor_link")          # raises on a file it did not write
    assert subprocess.run([str(tmp_path / "app")], capture_output=True, timeout=60).returncode == 0


@pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake missing")
def test_cmake_builds_library_and_example(fresh, tmp_path):
    src = tmp_path / "src"
    shutil.copytree(fresh / "dc_motor_link", src)
    b = tmp_path / "b"
    for cmd in (["cmake", "-S", str(src), "-B", str(b)], ["cmake", "--build", str(b)]):
        result = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        assert result.returncode == 0, result.stdout + result.stderr
    assert subprocess.run([str(b / "dc_motor_link_example")], capture_output=True, timeout=60).returncode == 0


def test_float_post_processing():
    text = "w[1]=sin(w[0]); w[2]=(2.*w[1]); w[3]=1.0000000000000000e-02; w[4]=fmin(w[2],w[3]); a[10]=w12;"
    out = csource.float_text(text)
    assert out == ("w[1]=sinf(w[0]); w[2]=(2.f*w[1]); w[3]=1.0000000000000000e-02f; w[4]=fminf(w[2],w[3]); "
                   "a[10]=w12;")


@pytest.mark.parametrize("other,flag", [({"precision": "float"}, "PRECISION_FLOAT"),
                                        ({"fusion": "ci"}, "FUSION_CI"),
                                        ({"oosm": "retrodict"}, "OOSM_RETRODICT")])
def test_library_refuses_a_header_from_another_build(tmp_path, host_cc, other, flag):
    """The internal header checks with #if that the public header was generated with the same
    options as the library: each source compiles with its own header, and none with the header
    of a build that differs in one option (the #error names the macro)."""
    mine = build.build("dc_motor_link", tmp_path / "mine")
    theirs = build.build("dc_motor_link", tmp_path / "theirs", **other)
    source = mine.path / "dc_motor_link_wire.c"
    ok = subprocess.run([host_cc, "-std=c99", "-c", str(source), "-o", str(tmp_path / "w.o"), "-I", str(mine.path)],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    shutil.copy(theirs.path / "dc_motor_link.h", mine.path / "dc_motor_link.h")
    bad = subprocess.run([host_cc, "-std=c99", "-c", str(source), "-o", str(tmp_path / "w.o"), "-I", str(mine.path)],
                         capture_output=True, text=True)
    assert bad.returncode != 0 and f"DC_MOTOR_LINK_{flag}" in bad.stderr and "another build" in bad.stderr


def test_cmake_and_make_carry_the_size_flags(fresh):
    """The generated CMake and Make fragments pass the flags the published sizes were measured
    with (check/target.py), so a user's firmware gets the sizes BENCHMARKS.md states."""
    from dfeif_codegen.check import target

    flags = ("-ffunction-sections", "-fdata-sections", "-fno-math-errno")
    assert all(f in target.CFLAGS for f in flags)
    cmake = (fresh / "dc_motor_link" / "CMakeLists.txt").read_text()
    make = (fresh / "dc_motor_link" / "dc_motor_link.mk").read_text()
    assert "target_compile_options(dc_motor_link PRIVATE\n        " + " ".join(flags) + ")" in cmake
    assert "DC_MOTOR_LINK_LIB_CFLAGS := " + " ".join(flags) in make


def _node_frames(host_cc, folder: Path) -> dict[str, int]:
    """`-fstack-usage`'s frame per function of the generated node.c in `folder` (-O2)."""
    subprocess.run([host_cc, "-std=c99", "-O2", "-fstack-usage", "-c", str(folder / "dc_motor_link_node.c"),
                    "-o", str(folder / "node.o")], check=True, capture_output=True)
    return {m.group(1): int(m.group(2)) for m in re.finditer(r":(\w+)\t(\d+)\t", (folder / "node.su").read_text())}


def test_replay_stack_is_the_compilers_and_warned_past_8_kib(tmp_path, host_cc):
    """The replay's frame grows with --max-lag: `-fstack-usage` on the generated node reports
    replay()'s frame at NMAX 32 and 4096, and the growth between the two is the estimate's to
    the byte (every array a multiple of 16 bytes there, so no alignment slack; the frame's fixed
    part, spills and inlined callees, cancels). `codegen build` warns past 8 KiB with that
    figure, and says nothing at the default NMAX. A retrodicting node's frames do not grow."""
    frame, said, retro = {}, {}, {}
    for lag in (32, 4096):
        result = cli_run("build", "--out", str(tmp_path / str(lag)), "--max-lag", str(lag))
        assert result.returncode == 0, result.stderr
        said[lag] = result.stderr
        frame[lag] = _node_frames(host_cc, tmp_path / str(lag) / "dc_motor_link")["replay"]
        other = tmp_path / f"retro{lag}"
        assert build.build("dc_motor_link", other, max_lag=lag, oosm="retrodict").n == 3
        retro[lag] = _node_frames(host_cc, other / "dc_motor_link")
    estimate = {lag: Options(ts=0.01, max_lag=lag).replay_stack(3) for lag in frame}      # the motor: n = 3
    assert frame[4096] - frame[32] == estimate[4096] - estimate[32]
    assert 0 <= frame[32] - estimate[32] <= 256, (frame, estimate)      # the fixed part: a few n-sized arrays
    assert said[32] == ""
    lines = said[4096].strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("codegen build: warning: ")
    assert f"about {estimate[4096]} bytes on the stack" in lines[0] and "--max-lag 4096" in lines[0]
    assert estimate[4096] > 8 * 1024 > Options(ts=0.01).replay_stack(3)
    assert retro[32] == retro[4096]
    assert Options(ts=0.01, max_lag=4096, oosm="retrodict", predictor="brunovsky").replay_stack(3) == 0


def test_user_model_banner_names_the_model_file_and_its_options(tmp_path):
    """A model file's build says to regenerate with the file's base name (the user's argument;
    `codegen build free_cart` fails, no such built-in; a base name keeps the output
    machine-independent) and every non-default option, a float one to all its digits."""
    spec = tmp_path / "sub" / "cart_v1.toml"
    spec.parent.mkdir()
    shutil.copy(ROOT / "tests" / "data" / "free_cart.toml", spec)
    module = build.build(str(spec), tmp_path / "out", max_lag=5, ts=0.0123456789, compile_check=False)
    command = "`codegen build cart_v1.toml --max-lag 5 --ts 0.0123456789`"
    header = (module.path / "free_cart.h").read_text()
    assert header.splitlines()[1] == f" * regenerate with {command}. */"
    manifest = json.loads((module.path / "manifest.json").read_text())
    assert manifest["_generated"].endswith(f"regenerate with {command}.")


def test_check_advice_carries_the_builds_options(tmp_path):
    """`codegen build --check`'s advice for a stale float build (build.rebuild_advice) keeps
    --precision float and --out; checked without it, it also says what the folder was built with."""
    spec = tmp_path / "cart.toml"
    shutil.copy(ROOT / "tests" / "data" / "free_cart.toml", spec)
    out = tmp_path / "g2"
    build.build(str(spec), out, precision="float", compile_check=False)
    assert build.rebuild_advice(str(spec), out, precision="float") == \
        f"run `codegen build {spec} --precision float --out {out}`"
    assert build.rebuild_advice(str(spec), out) == (f"run `codegen build {spec} --out {out}`; it was built with "
                                                    f"`codegen build {spec} --precision float --out {out}`")
