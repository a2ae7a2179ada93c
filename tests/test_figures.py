"""Figures in the model's own names and units (experiment/figures.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dfeif_codegen.experiment import closed_loop as ex
from dfeif_codegen.experiment import figures


def test_labels_carry_the_models_units():
    """The motor's TOML gives theta in rad and V in V: derivatives get rad/s, rad/s^2."""
    flat = ex._flat("dc_motor_link")
    assert figures.state_labels(flat) == ["theta [rad]", "theta' [rad/s]", "theta'' [rad/s^2]"]
    assert figures.input_labels(flat.model) == ["V [V]"]
    arm = ex._flat("two_link_arm")
    assert figures.state_labels(arm)[3:] == ["q2 [rad]", "q2' [rad/s]", "q2'' [rad/s^2]"]


def test_row_text():
    assert figures.row_text("  25  30  0.6") == "(d1, d2, p) = (25, 30, 0.6)"


def test_every_figure_renders(tmp_path):
    """matplotlib is installed by scripts/setup-tests.sh (the [plot] extra): rendered, not skipped."""
    flat = ex._flat("dc_motor_link")
    t = np.arange(200) * 0.01
    truth = np.column_stack([np.sin(t), np.cos(t), -np.sin(t)])
    est = truth + 1e-3
    figures.states_figure(tmp_path / "a.png", "t", flat, t, est, truth, truth, np.zeros((200, 1)))
    figures.error_figure(tmp_path / "b.png", "t", flat, t, est, truth, np.full((200, 3), 1e-6))
    lags = np.where(np.arange(400).reshape(2, 200) % 3 == 0, 5, 0)
    lags[0, 7] = -1
    figures.delay_figure(tmp_path / "c.png", "t", t, lags, 0.01)
    figures.comparison_figure(tmp_path / "d.png", "t", flat, ["(0, 0, 0)", "(4, 6, 0.8)"],
                              {"DF": (np.ones((2, 3)), np.full((2, 3), 0.1)), "EKF": (np.ones((2, 3)), np.zeros((2, 3)))})
    for name in "abcd":
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000


def test_legends_cover_no_data(tmp_path, monkeypatch):
    """Issue 24 finding 9: every legend lies outside every panel's plotting area (so it covers no
    data) and inside the figure (so it is not cut off). Checked on the drawn figure's pixel boxes.
    The title too: the longest simulate writes (Fig. 10's, a 17-character model name, three
    nodes' delay row) lies inside the figure and above every panel and legend."""
    import matplotlib.pyplot as plt

    drawn, close = [], plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: drawn.append(fig))
    flat = ex._flat("dc_motor_link")
    title = (f"Fig. 10: {'m' * 17}, camera -> node delays at {figures.row_text('25  30  30  0.6')} (sinusoid run; "
             "the seed's draws, the same for every reference): late with probability p by 1..d_i steps")
    t = np.arange(300) * 0.01
    truth = np.column_stack([np.sin(t * (i + 1)) for i in range(flat.n)])
    figures.states_figure(tmp_path / "a.png", title, flat, t, truth + 1e-3, truth, truth, np.ones((300, flat.m)))
    figures.error_figure(tmp_path / "b.png", title, flat, t, truth + 1e-3, truth, np.full((300, flat.n), 1e-6))
    lags = np.where(np.arange(600).reshape(2, 300) % 3 == 0, 5, 0)
    lags[0, 7] = -1
    figures.delay_figure(tmp_path / "c.png", title, t, lags, 0.01)
    figures.comparison_figure(tmp_path / "d.png", title, flat, ["(0, 0, 0)", "(4, 6, 0.8)"],
                              {"df": (np.ones((2, flat.n)), np.full((2, flat.n), 0.1)),
                               "ekf": (np.ones((2, flat.n)), np.zeros((2, flat.n)))})
    assert len(drawn) == 4
    for fig in drawn:
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        page = fig.bbox
        panels = [ax for ax in fig.axes if ax.get_visible()]
        legends = [ax.get_legend() for ax in panels if ax.get_legend() is not None]
        assert legends
        head = fig._suptitle.get_window_extent(r)
        assert page.x0 - 1 <= head.x0 and head.x1 <= page.x1 + 1 and head.y1 <= page.y1 + 1, "the title is cut"
        for box in [leg.get_window_extent(r) for leg in legends] + [ax.get_window_extent(r) for ax in panels]:
            assert box.y1 <= head.y0 + 1, "the title overlaps a panel or a legend"
        for leg in legends:
            box = leg.get_window_extent(r)
            assert page.x0 - 1 <= box.x0 and box.x1 <= page.x1 + 1 and page.y0 - 1 <= box.y0 and box.y1 <= page.y1 + 1
            for ax in panels:
                area = ax.get_window_extent(r)
                inter_w = min(box.x1, area.x1) - max(box.x0, area.x0)
                inter_h = min(box.y1, area.y1) - max(box.y0, area.y0)
                assert inter_w <= 1 or inter_h <= 1, "a legend covers a panel's plotting area"
        close(fig)


def test_filters_figure_with_every_filters_runs_failed_draws_none(tmp_path):
    """`simulate --filters ekf --plot DIR` where every EKF run failed (a plant 20% off): its table
    has no means (KeyError), so there is nothing to compare; no figure is written, where a legend
    of no series raised ValueError and the sweep's tables were lost (exit 3). With one filter
    that ran, its figure is written."""
    from types import SimpleNamespace

    flat = ex._flat("dc_motor_link")

    class Empty:
        def mean(self, key):
            raise KeyError(key)

        ci95 = mean

    ran = SimpleNamespace(mean=lambda key: np.ones((1, 3)), ci95=lambda key: np.zeros((1, 3)))
    result = SimpleNamespace(settings={"filters": ["ekf"]}, rows=[SimpleNamespace(d=(0, 0), p=0.0)],
                             tables=[SimpleNamespace(reference="sinusoid")],
                             table=lambda ref, label, rule: Empty() if label == "ekf-replay" else ran)
    assert figures.filters_figures(str(tmp_path), result, flat) == []
    assert list(tmp_path.iterdir()) == []
    result.settings["filters"] = ["ekf", "ukf"]
    written = figures.filters_figures(str(tmp_path), result, flat)
    assert written == [str(tmp_path / figures.comparison_name("sinusoid"))] and Path(written[0]).stat().st_size > 10_000
