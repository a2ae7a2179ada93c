"""Figures of `codegen simulate --plot`: what a reader wants to see, in the model's own names and
units. Each canonical state is labelled by its flat output and derivative order with the unit
that implies (theta, theta' [rad/s], theta'' [rad/s^2]); the input by its name and unit.

- states against the reference (the reference drawn wide underneath, so it stays visible), one
  legend per panel (above it, outside the axes), and the input;
- the estimation error x_hat - x with the filter's own +-3 sigma band (where a consistent filter
  keeps 99.7% of it);
- the delays: each late frame as a dot at (taken at, lag), per node, with the shares of on-time,
  late and dropped frames in the legend, and the row's settings in the title;
- the derivative-free filter against the EKF and UKF: master RMSE per state and row, with 95%
  intervals.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from dfeif_codegen.errors import SetupError


def pyplot():
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise SetupError("--plot needs matplotlib: pip install 'dfeif-codegen[plot]'") from None
    return plt


def _unit_of(model, expr) -> str:
    names = {s.name: s.unit for s in model.states}
    return names.get(str(expr), "")


def _per_s(unit: str, k: int) -> str:
    if k == 0:
        return unit
    tail = "/s" if k == 1 else f"/s^{k}"
    if not unit:
        return f"1{tail}"
    if unit.endswith("/s"):                       # rad/s -> rad/s^2 for the next order
        return unit[:-2] + ("/s^2" if k == 1 else f"/s^{k + 1}")
    return unit + tail


def state_labels(flat) -> list[str]:
    """'theta [rad]', "theta' [rad/s]", ... per canonical state, chain by chain."""
    out = []
    for chain, output in zip(flat.chains, flat.model.outputs):
        unit = _unit_of(flat.model, output.expr)
        for k in range(chain.degree):
            name = chain.output + ("'" * k if k <= 3 else f"^({k})")
            u = _per_s(unit, k)
            out.append(f"{name} [{u}]" if u else name)
    return out


def input_labels(model) -> list[str]:
    return [f"{u.name} [{u.unit}]" if u.unit else u.name for u in model.inputs]


def row_text(label: str) -> str:
    """'25  30  0.6' (simulate's row label) -> '(d1, d2, p) = (25, 30, 0.6)'."""
    parts = label.split()
    if len(parts) < 2:
        return label
    ds = ", ".join(f"d{i + 1}" for i in range(len(parts) - 1))
    return f"({ds}, p) = ({', '.join(parts)})"


def _legend(ax, ncol: int = 1) -> None:
    """The legend in one line above the panel, outside the axes: it never covers data
    (tight_layout makes room for it)."""
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=ncol, borderaxespad=0.2,
              framealpha=0.9)


def _grid(plt, panels, height=2.3):
    cols = 2 if panels > 1 else 1
    rows = (panels + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(11, height * rows), squeeze=False)
    for ax in axes.flat[panels:]:
        ax.set_visible(False)
    return fig, axes.flat


# Characters of a title per inch of figure width: matplotlib's 12-point sans-serif averages about
# 0.08 in per character, so 10 per inch leaves a margin for wide letters.
TITLE_CHARS_PER_INCH = 10


def _save(plt, fig, title, path) -> None:
    """Title (wrapped to the figure's width: a long model name and delay row would cut it at both
    edges), layout, the PNG at 110 dpi, and the figure closed (pyplot keeps open ones alive)."""
    fig.suptitle(textwrap.fill(title, width=int(fig.get_figwidth() * TITLE_CHARS_PER_INCH)))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def states_figure(path, title, flat, t, est, truth, ref, u, who="estimate"):
    plt = pyplot()
    labels, ulabels = state_labels(flat), input_labels(flat.model)
    fig, axes = _grid(plt, len(labels) + len(ulabels))
    for i, label in enumerate(labels):
        ax = axes[i]
        ax.plot(t, ref[:, i], color="tab:orange", lw=3.0, alpha=0.45, label="reference")
        ax.plot(t, truth[:, i], "k", lw=0.8, label="true")
        ax.plot(t, est[:, i], color="tab:blue", ls="--", lw=0.8, label=who)
        ax.plot(t, ref[:, i], color="tab:red", lw=0.8, zorder=5)     # and thin on top: seen through noise
        ax.set_ylabel(label)
        _legend(ax, 3)
    for j, label in enumerate(ulabels):
        ax = axes[len(labels) + j]
        ax.plot(t, u[:, j], color="tab:green", lw=0.8, label="control input")
        ax.set_ylabel(label)
        _legend(ax)
    for ax in axes:
        ax.set_xlabel("time [s]")
    _save(plt, fig, title, path)


def error_figure(path, title, flat, t, est, truth, var, metrics_from=1.0):
    """x_hat - x per state with +-3 sqrt(P_ii); the share of steps inside the band in the legend."""
    plt = pyplot()
    labels = state_labels(flat)
    err = est - truth
    for c in flat.chains:
        if c.angle:
            err[:, c.offset] = (err[:, c.offset] + np.pi) % (2 * np.pi) - np.pi
    sigma = 3 * np.sqrt(np.maximum(var, 0))
    keep = t >= metrics_from
    fig, axes = _grid(plt, len(labels))
    for i, label in enumerate(labels):
        ax = axes[i]
        inside = np.mean(np.abs(err[keep, i]) <= sigma[keep, i])
        ax.fill_between(t, -sigma[:, i], sigma[:, i], color="tab:blue", alpha=0.2, lw=0,
                        label="±3σ of the filter")
        ax.plot(t, err[:, i], "k", lw=0.6, label=f"error ({100 * inside:.1f}% inside)")
        lim = 1.5 * np.percentile(sigma[keep, i], 99) if keep.any() else None
        if lim:
            ax.set_ylim(-lim, lim)
        ax.set_ylabel("error of " + label)
        _legend(ax, 2)
        ax.set_xlabel("time [s]")
    _save(plt, fig, title, path)


def delay_figure(path, title, t, delays, ts):
    """Per node: each late frame as a dot (time taken, lag in steps), dropped frames as ticks."""
    plt = pyplot()
    delays = np.asarray(delays)
    fig, axes = plt.subplots(delays.shape[0], 1, figsize=(11, 2.3 * delays.shape[0]), squeeze=False, sharex=True)
    top = max(int(delays.max()), 1)
    for i, ax in enumerate(axes.flat):
        lag = delays[i]
        late, drop = lag > 0, lag < 0
        on = np.mean(lag == 0)
        ax.plot(t[late], lag[late], ".", ms=2.5, color="tab:red",
                label=f"late frame: {100 * late.mean():.0f}% (mean {lag[late].mean() if late.any() else 0:.1f} steps)")
        if drop.any():
            ax.plot(t[drop], np.full(drop.sum(), -0.5), "|", color="k", ms=4, label=f"dropped: {100 * drop.mean():.0f}%")
        ax.axhline(0, color="tab:green", lw=1.0, label=f"on time: {100 * on:.0f}%")
        ax.set_ylim(-1, top + 1)
        ax.set_ylabel(f"node {i + 1}: delay\n[steps of {1000 * ts:g} ms]")
        _legend(ax, 3)
        sec = ax.secondary_yaxis("right", functions=(lambda s: s * ts * 1000, lambda ms: ms / (ts * 1000)))
        sec.set_ylabel("[ms]")
    axes.flat[-1].set_xlabel("time the frame was taken [s]")
    _save(plt, fig, title, path)


def comparison_figure(path, title, flat, row_labels, series):
    """`series`: {filter name: (mean (rows, n), ci95 (rows, n))} of the master RMSE per state."""
    plt = pyplot()
    labels = state_labels(flat)
    fig, axes = _grid(plt, len(labels), height=2.6)
    width = 0.8 / max(len(series), 1)
    xs = np.arange(len(row_labels))
    for i, label in enumerate(labels):
        ax = axes[i]
        for j, (name, (mean, half)) in enumerate(series.items()):
            ax.bar(xs + (j - (len(series) - 1) / 2) * width, np.asarray(mean)[:, i], width,
                   yerr=np.nan_to_num(np.asarray(half)[:, i]), capsize=2, label=name)
        ax.set_yscale("log")
        ax.set_xticks(xs, row_labels, fontsize=7)
        ax.set_ylabel("master RMSE of\n" + label)
        _legend(ax, len(series))
        ax.set_xlabel("delay row (d1, d2, p)")
    _save(plt, fig, title, path)


def figure_names(ref: str, nodes: int) -> list[str]:
    """The files `--plot` writes per reference: Figs 9 and 10, one per node, the master under
    delays, its error without and with delays."""
    last = 11 + nodes
    return [f"fig09_{ref}_master_no_delay.png", f"fig10_{ref}_delays.png",
            *(f"fig{11 + i}_{ref}_node{i + 1}_delay.png" for i in range(nodes)),
            f"fig{last}_{ref}_master_delay.png",
            f"fig{last + 1}_{ref}_master_error_no_delay.png", f"fig{last + 1}_{ref}_master_error_delay.png"]


def comparison_name(ref: str) -> str:
    """The file `--filters ... --plot` adds per reference."""
    return f"compare_{ref}_filters.png"


def simulation_figures(directory: str, figures: dict, flat, metrics_from: float = 1.0) -> list[str]:
    """`simulate --plot`: PNG figures like the chapter's Figs 9-13: states against the
    reference, the estimation error with its +-3 sigma band (its share of steps inside counted
    from the scenario's `metrics_from`, as the tables are), the delays."""
    pyplot()
    folder = Path(directory)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    name = flat.model.name

    def save(path):
        written.append(str(path))
        return path

    for ref, fig in figures.items():
        a, b = fig["no_delay"], fig["delay"]
        how = f"{fig['method']} + {fig['fusion']}"
        b = {**b, "row": row_text(b["row"])}
        t = np.asarray(a["t"])
        names = figure_names(ref, len(b["node_x"]))
        states_figure(save(folder / names[0]),
                           f"Fig. 9: {name}, master estimate without delays ({ref} reference, {how})", flat,
                           t, np.asarray(a["x"]), np.asarray(a["zeta"]), np.asarray(a["ref"]), np.asarray(a["u"]),
                           who="master estimate")
        ts = float(t[1] - t[0]) if len(t) > 1 else 1.0
        delay_figure(save(folder / names[1]),
                          f"Fig. 10: {name}, camera -> node delays at {b['row']} ({ref} run; the seed's draws, "
                          "the same for every reference): late with probability p by 1..d_i steps",
                          np.asarray(b["t"]), b["delays"], ts)
        node_x = np.asarray(b["node_x"])
        for i in range(node_x.shape[0]):
            states_figure(save(folder / names[2 + i]),
                               f"Fig. {11 + i}: {name}, node {i + 1} under delays {b['row']} ({ref})", flat,
                               b["t"], node_x[i], np.asarray(b["zeta"]), np.asarray(b["ref"]), np.asarray(b["u"]),
                               who=f"node {i + 1} estimate")
        last = 11 + node_x.shape[0]
        states_figure(save(folder / names[-3]),
                           f"Fig. {last}: {name}, master under delays {b['row']} ({ref}, {how})", flat,
                           b["t"], np.asarray(b["x"]), np.asarray(b["zeta"]), np.asarray(b["ref"]), np.asarray(b["u"]),
                           who="master estimate")
        for key, label in (("no_delay", "without delays"), ("delay", f"under delays {b['row']}")):
            d = fig[key]
            if "P_diag" in d:
                error_figure(save(folder / names[-2 if key == "no_delay" else -1]),
                                  f"{name}: master estimation error {label} ({ref}, {how})", flat,
                                  np.asarray(d["t"]), np.asarray(d["x"]), np.asarray(d["zeta"]), np.asarray(d["P_diag"]),
                                  metrics_from)
    return written


def filters_figures(directory: str, result, flat) -> list[str]:
    """`simulate --filters ... --plot DIR`: per reference, the master RMSE per state and delay row
    of each filter on the same recordings (replay + difference), with 95% intervals."""
    written = []
    # the axis is labelled "delay row (d1, d2, p)": the ticks carry the numbers only (six rows of
    # "(d1, d2, p) = (...)" overlapped in a half-width panel)
    labels = ["(" + ", ".join([*(str(d) for d in row.d), f"{row.p:g}"]) + ")" for row in result.rows]
    for ref in dict.fromkeys(t.reference for t in result.tables):
        series = {}
        for k in result.settings["filters"]:
            table = result.table(ref, f"{k}-replay", "difference")
            try:
                series[k] = (table.mean("rmse_master"), table.ci95("rmse_master"))
            except KeyError:            # every run of this filter failed: nothing to draw
                continue
        if not series:                  # every filter's: no figure (a legend of none raised)
            continue
        path = Path(directory) / comparison_name(ref)
        comparison_figure(path, f"{flat.model.name}: master RMSE per filter, same recordings ({ref})", flat,
                          labels, series)
        written.append(str(path))
    return written
