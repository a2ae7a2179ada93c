"""Input files read boundedly and output files replaced only when the toolkit wrote them
(dfeif_codegen/paths.py): a FIFO or a huge file is refused before it is read, and each
command's earlier output of its kind is recognised (so a rerun to the same path works) while
anything else at that path is left alone."""

from __future__ import annotations

import json
import os
import shutil
import threading
from pathlib import Path

import pytest

from dfeif_codegen import cli
from dfeif_codegen.check import bench
from dfeif_codegen.errors import ModelError
from dfeif_codegen.paths import MAX_TEXT_BYTES, OutputPathError, read_text
from dfeif_codegen.reproduction import run as reproduction

ROOT = Path(__file__).resolve().parents[1]
SMALL = "[scenario]\nduration = 1.0\nruns = 1\nmetrics_from = 0.2\nreferences = [\"seesaw\"]\n"


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path):
    """A FIFO would block the read until a writer came; the writer here comes after 20 s, so a
    reader that blocked would see an empty file and fail differently (and late)."""
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this system")
    fifo = tmp_path / "m.toml"
    os.mkfifo(fifo)
    timer = threading.Timer(20.0, lambda: open(fifo, "w").close())
    timer.daemon = True
    timer.start()
    try:
        with pytest.raises(ModelError, match=r"m\.toml: cannot read model file \(not a regular file"):
            read_text(fifo, "m.toml", ModelError, "model")
    finally:
        timer.cancel()


def test_a_file_over_the_size_limit_is_refused_and_one_at_it_is_read(tmp_path):
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * (MAX_TEXT_BYTES + 1))
    with pytest.raises(ModelError, match=f"big.toml: model file of {MAX_TEXT_BYTES + 1} bytes: at most 16 MiB"):
        read_text(big, "big.toml", ModelError, "model")
    big.write_bytes(b"#" * (MAX_TEXT_BYTES - 1) + b"\n")
    assert len(read_text(big, "big.toml", ModelError, "model")) == MAX_TEXT_BYTES


def test_crlf_input_reads_as_before(tmp_path):
    """Line ends as open()'s text mode gave them (the model's line numbers count on it)."""
    path = tmp_path / "s.toml"
    path.write_bytes(b"a = 1\r\nb = 2\rc = 3\n")
    assert read_text(path, "s.toml", ModelError, "scenario") == "a = 1\nb = 2\nc = 3\n"


def _simulate(tmp_path, capsys, *extra) -> int:
    scenario = tmp_path / "s.toml"
    scenario.write_text(SMALL)
    code = cli.main(["simulate", "--scenario", str(scenario), "--engine", "reference", "--quiet", *extra])
    capsys.readouterr()
    return code


def test_simulate_replaces_its_own_outputs_and_nothing_else(tmp_path, capsys):
    """A rerun to the same --json/--csv/--results paths replaces them (each recognised as
    simulate's); a torn results file from an interrupted run is still its own."""
    out = {"--json": tmp_path / "r.json", "--csv": tmp_path / "r.csv", "--results": tmp_path / "r.jsonl"}
    argv = [a for flag, path in out.items() for a in (flag, str(path))]
    assert _simulate(tmp_path, capsys, *argv) == 0
    first = {flag: path.read_bytes() for flag, path in out.items()}
    assert set(json.loads(first["--json"])) >= {"settings", "tables"}
    assert first["--csv"].startswith(b"reference,method,fusion,row,seed,error,rmse_master_x1,")
    assert json.loads(first["--results"].splitlines()[0])["engine"] == "reference"
    out["--results"].write_bytes(first["--results"][:40])     # torn mid-record, but still recognisably its own
    out["--csv"].write_bytes(first["--csv"].splitlines(keepends=True)[0])
    assert _simulate(tmp_path, capsys, *argv) == 0
    assert out["--csv"].read_bytes() == first["--csv"]          # the same seed, the same rows
    assert out["--results"].read_bytes() == first["--results"]


def test_simulate_leaves_another_programs_json_alone(tmp_path, capsys):
    mine = tmp_path / "mine.json"
    mine.write_text('{"settings": {}, "tables": []}\n')     # close, but not simulate's key set
    assert _simulate(tmp_path, capsys, "--json", str(mine)) == 2
    assert mine.read_text() == '{"settings": {}, "tables": []}\n'


def test_bench_and_reproduce_recognise_their_committed_outputs(tmp_path):
    """BENCHMARKS.md and docs/experiment.md (with its data file), copied, are replaceable by
    their commands; a user's file of the same name is not."""
    shutil.copy(ROOT / "BENCHMARKS.md", tmp_path / "B.md")
    bench.check_out(str(tmp_path / "B.md"))
    shutil.copy(ROOT / "docs" / "experiment.md", tmp_path / "e.md")
    shutil.copy(ROOT / "docs" / "experiment.json", tmp_path / "e.json")
    reproduction.check_doc(tmp_path / "e.md")
    (tmp_path / "e.json").write_text("{}\n")
    with pytest.raises(OutputPathError, match="e.json: exists and was not written by codegen reproduce"):
        reproduction.check_doc(tmp_path / "e.md")
    (tmp_path / "B.md").write_text("# My benchmarks\n")
    with pytest.raises(OutputPathError, match="B.md: exists and was not written by codegen bench"):
        bench.check_out(str(tmp_path / "B.md"))


def test_the_documents_generated_line_is_in_its_template():
    """check_doc recognises the document by this line: the template must keep writing it."""
    from dfeif_codegen.reproduction import document

    assert reproduction.GENERATED in document.template_text()
    assert reproduction.GENERATED in (ROOT / "docs" / "experiment.md").read_text()[:4096]


def test_network_bench_leaves_a_users_file_alone(tmp_path, capsys):
    """`codegen network --bench FILE` rewrites the network section of a report of ours; a user's
    file of that name is refused before anything is measured, and left as it was."""
    from dfeif_codegen import cli

    notes = tmp_path / "notes.md"
    notes.write_text("my notes\n")
    assert cli.main(["network", "--bench", str(notes)]) == 2
    assert notes.read_text() == "my notes\n"
    assert "--bench " + str(notes) + ": exists and was not written by codegen bench" in capsys.readouterr().err


def test_reproduce_replaces_its_own_figures_and_no_one_elses(tmp_path, capsys):
    """`reproduce --doc` copies figures beside the document: a file at a figure's path that is
    not a matplotlib PNG (a user's) is refused before any run, named, and left as it was, as is
    a user's OUT/experiment.md; a figure an earlier rendering copied there is replaced. A figure
    new to this rendering is checked when its name is known, before anything is written."""
    doc = tmp_path / "e.md"
    shutil.copy(ROOT / "docs" / "experiment.md", doc)
    shutil.copy(ROOT / "docs" / "experiment.json", tmp_path / "e.json")
    figure = tmp_path / "figures" / "compare_dc_motor_link.png"
    figure.parent.mkdir()
    figure.write_bytes(b"my own chart\n")
    argv = ["reproduce", "--quick", "--runs", "2", "--quiet", "--out", str(tmp_path / "out")]
    assert cli.main([*argv, "--doc", str(doc)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{figure}: exists and was not written by codegen reproduce" in err[0]
    assert figure.read_bytes() == b"my own chart\n" and not (tmp_path / "out").exists()    # refused before any run
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "experiment.md").write_text("my notes\n")
    assert cli.main(argv) == 2
    assert "experiment.md: exists and was not written by codegen reproduce" in capsys.readouterr().err
    assert (tmp_path / "out" / "experiment.md").read_text() == "my notes\n"

    theirs = (ROOT / "docs" / "figures" / "compare_two_link_arm.png").read_bytes()   # another rendering's
    figure.write_bytes(theirs)
    reproduction.check_doc(doc)
    out = tmp_path / "out"
    fresh = (ROOT / "docs" / "figures" / "compare_dc_motor_link.png").read_bytes()
    (out / "figures" / "motor").mkdir(parents=True)
    (out / "figures" / "compare_dc_motor_link.png").write_bytes(fresh)
    (out / "figures" / "motor" / "fig1.png").write_bytes(fresh)
    text = "x\n![chart](figures/compare_dc_motor_link.png)\n![one](figures/motor/fig1.png)\n"
    (tmp_path / "figures" / "motor").mkdir()
    (tmp_path / "figures" / "motor" / "fig1.png").write_text("a user's file at a new figure's name\n")
    with pytest.raises(OutputPathError, match="fig1.png: exists and was not written by codegen reproduce"):
        reproduction.publish(text, {}, out, doc)
    assert figure.read_bytes() == theirs and doc.read_bytes() == (ROOT / "docs" / "experiment.md").read_bytes()
    assert (tmp_path / "e.json").read_bytes() == (ROOT / "docs" / "experiment.json").read_bytes()
    (tmp_path / "figures" / "motor" / "fig1.png").unlink()
    reproduction.publish(text, {}, out, doc)
    assert figure.read_bytes() == fresh and (tmp_path / "figures" / "motor" / "fig1.png").read_bytes() == fresh
    assert doc.read_text() == text
    (out / "experiment.md").unlink()        # the user's notes, moved away
    inside = reproduction.publish(text, {}, out, out / "experiment.md")     # --doc inside OUT: figures in place
    assert inside[-1] == str(out / "figures" / "motor" / "fig1.png") and (out / "experiment.md").read_text() == text


def test_simulate_plot_replaces_its_own_figures_and_no_one_elses(tmp_path, capsys):
    """`simulate --plot DIR` saves figures under names of its own: a user's file at one of them
    is refused once the plan names it, before any run (exit 2, the path named, the file kept,
    nothing written); a figure an earlier --plot saved there (a matplotlib PNG) may be replaced."""
    from types import SimpleNamespace

    from dfeif_codegen.experiment.plan import check_figures

    plots = tmp_path / "plots"
    plots.mkdir()
    mine = plots / "fig10_sinusoid_delays.png"
    mine.write_bytes(b"\x89PNG\r\n\x1a\nmy own chart")
    argv = ["simulate", "dc_motor_link", "--runs", "1", "--reference", "sinusoid", "--quiet", "--plot", str(plots)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{mine}: exists and was not written by codegen simulate" in err[0]
    assert mine.read_bytes() == b"\x89PNG\r\n\x1a\nmy own chart" and [p.name for p in plots.iterdir()] == [mine.name]
    mine.write_bytes((ROOT / "docs" / "figures" / "compare_dc_motor_link.png").read_bytes())
    plan = SimpleNamespace(refs=["sinusoid"], nodes=2, filters=["ekf"])
    check_figures(str(plots), plan)                  # an earlier figure: no error
    (plots / "compare_sinusoid_filters.png").write_text("notes\n")
    with pytest.raises(OutputPathError, match="compare_sinusoid_filters.png: exists and was not written"):
        check_figures(str(plots), plan)
