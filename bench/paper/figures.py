"""Figures of ``livedic bench paper`` (matplotlib, Agg) and the CSV beside each one."""

import csv
import os

import numpy as np

from livedic.bench.paper.runs import LABELS, RADIUS_LABELS, RADIUS_SEARCHES, REFERENCE_SEARCH, SEARCHES, SUBPIXELS

COLOURS = {
    "exhaustive": "0.45",
    "fft-cc": "0.2",
    "improved-wso (paper)": "tab:pink",
    "coarse-fine": "tab:blue",
    "pso": "tab:orange",
    "wso": "tab:green",
    "improved-wso": "tab:red",
    "surface-fit": "tab:blue",
    "gradient": "tab:orange",
    "newton-raphson": "tab:green",
    "improved-surface-fit": "tab:red",
    "icgn": "tab:purple",
    "icgn2": "tab:brown",
}
MARKERS = {"coarse-fine": "s", "pso": "^", "wso": "v", "improved-wso": "o", "exhaustive": "x", "fft-cc": "+",
           "improved-wso (paper)": "P",
           "surface-fit": "s", "gradient": "^", "newton-raphson": "v", "improved-surface-fit": "o", "icgn": "D",
           "icgn2": "*"}


# The figures' style, applied around their drawing only (matplotlib's global settings are the process's:
# the export's maps drawn later in the same process must not inherit them).
_STYLE = {"figure.dpi": 110, "savefig.dpi": 110, "font.size": 9, "axes.grid": True, "grid.alpha": 0.3,
          "legend.fontsize": 8, "axes.titlesize": 10}


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


_IMAGES = {"kind": "float"}


def _noise_title(sigma):
    kind = _IMAGES["kind"]
    if sigma == 0:
        return f"noise-free ({kind} images)"
    return f"Gaussian noise sigma = {sigma:g} grey levels on both images ({kind})"


def write_csv(path, rows, columns):
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_fmt(row.get(c)) for c in columns])


def _fmt(value):
    if isinstance(value, float):
        return f"{value:.6g}"
    return value


def draw_all(results, cfg, out):
    """Draw every figure whose data exists; returns {figure key: [file names]}."""
    plt = _plt()
    with plt.rc_context(_STYLE):
        return _draw_all(plt, results, cfg, out)


def _draw_all(plt, results, cfg, out):
    _IMAGES["kind"] = "exact float" if cfg.bit_depth is None else f"{cfg.bit_depth}-bit"
    written = {}

    def save(fig, name):
        fig.savefig(os.path.join(out, name), bbox_inches="tight")
        plt.close(fig)
        written.setdefault(name.split("_")[0], []).append(name)

    _integer_figures(plt, save, written, results, cfg, out)
    _subpixel_figures(plt, save, written, results, out)

    if "subpixel_clean" in results or "measure_timing" in results:
        rows = table1_rows(results)
        if rows:
            write_csv(os.path.join(out, "table1_time.csv"), rows,
                      ["method", "stage_s", "stage_us_per_point", "stage_pct_of_nr", "measure_s",
                       "measure_us_per_point", "measure_pct_of_nr", "paper_s", "paper_pct_of_nr"])
            save(_table1(plt, rows), "table1_time.png")
            written["table1"].append("table1_time.csv")

    if "radius" in results:
        write_csv(os.path.join(out, "fig_radius.csv"), results["radius"]["rows"],
                  ["radius", "generator", "sigma", "method", "n", "success_pct", "misses", "evaluations",
                   "us_per_point", "shift_u", "shift_v"])
        save(_fig_radius(plt, results["radius"]["summary"]), "fig_radius.png")
        written["fig"].append("fig_radius.csv")

    fields = [results[k] for k in ("field_clean", "field_noisy") if k in results]
    if fields:
        long_rows = []
        for block in fields:
            for method, u in block["u"].items():
                for (x, y), value in zip(block["points"], u):
                    long_rows.append(dict(sigma=block["sigma"], method=method, x=int(x), y=int(y), u=float(value)))
        write_csv(os.path.join(out, "fig12_u_field.csv"), long_rows, ["sigma", "method", "x", "y", "u"])
        written.setdefault("fig12", []).append("fig12_u_field.csv")
        for block in fields:
            save(_fig12(plt, block), "fig12_u_field.png" if block["sigma"] == 0 else "fig12_u_field_noise.png")
    return written


def _integer_figures(plt, save, written, results, cfg, out):
    """Figs 9 and 10 with their CSVs (integer searches)."""
    integer = [results[k] for k in ("integer_clean", "integer_noisy") if k in results]
    if integer:
        rows = [r for block in integer for r in block["rows"]]
        write_csv(os.path.join(out, "fig09_success.csv"), rows,
                  ["sigma", "method", "displacement", "n", "failed", "success_pct", "truth_pct",
                   "evaluations", "calls", "time_s", "time_ms_per_point"])
        written.setdefault("fig09", []).append("fig09_success.csv")
        for block in integer:
            sigma = block["rows"][0]["sigma"]
            save(_fig09(plt, block, sigma, cfg), "fig09_success.png" if sigma == 0 else "fig09_success_noise.png")
        cost_rows = []
        for block in integer:
            for method, entry in block["cost"].items():
                cost_rows.append(dict(sigma=block["rows"][0]["sigma"], method=method, **entry))
        write_csv(os.path.join(out, "fig10_cost.csv"), cost_rows,
                  ["sigma", "method", "n", "success_pct", "time_s", "time_ms_per_point", "evaluations", "calls",
                   "time_vs_pso", "time_vs_coarse-fine", "evaluations_vs_pso", "evaluations_vs_coarse-fine"])
        save(_fig10(plt, integer), "fig10_cost.png")
        written["fig10"].append("fig10_cost.csv")


def _subpixel_figures(plt, save, written, results, out):
    """Figs 11 and 7 with their CSVs (sub-pixel methods, fitting distance)."""
    sub = [results[k] for k in ("subpixel_clean", "subpixel_noisy") if k in results]
    if sub:
        rows = [r for block in sub for r in block["rows"]]
        write_csv(os.path.join(out, "fig11_subpixel.csv"), rows,
                  ["sigma", "method", "displacement", "n", "failed", "mean_u", "sd_u", "rmse_u", "max_abs_u",
                   "mean_v", "sd_v"])
        written.setdefault("fig11", []).append("fig11_subpixel.csv")
        for block in sub:
            sigma = block["rows"][0]["sigma"]
            save(_fig11(plt, block, sigma), "fig11_subpixel.png" if sigma == 0 else "fig11_subpixel_noise.png")
        noisy = results.get("subpixel_noisy", {}).get("icgn_noise")
        if noisy:
            write_csv(os.path.join(out, "fig11_icgn_noise_check.csv"), noisy["rows"],
                      ["displacement", "n", "measured_sd", "predicted_sd", "ratio"])
            written["fig11"].append("fig11_icgn_noise_check.csv")
        fit_rows = [r for block in sub for r in block["fit_rows"]]
        if fit_rows:
            write_csv(os.path.join(out, "fig07_fitting_distance.csv"), fit_rows,
                      ["sigma", "displacement", "spacing", "n", "failed", "mean_u", "sd_u", "rmse_u", "max_abs_u"])
            written.setdefault("fig07", []).append("fig07_fitting_distance.csv")
            for block in sub:
                if block["fit_rows"]:
                    sigma = block["rows"][0]["sigma"]
                    save(_fig07(plt, block["fit_rows"], sigma),
                         "fig07_fitting_distance.png" if sigma == 0 else "fig07_fitting_distance_noise.png")


# --------------------------------------------------------------------------- individual figures


def _fig09(plt, block, sigma, cfg):
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for ax, key, title in ((axes[0], "success_pct", "(a) success = exhaustive-search argmax"),
                           (axes[1], "truth_pct", "(b) success = within 0.5 px of the true shift")):
        for method in SEARCHES + (REFERENCE_SEARCH,):
            rows = [r for r in block["rows"] if r["method"] == method]
            if not rows or (method == REFERENCE_SEARCH and key == "success_pct"):
                continue
            style = dict(color=COLOURS[method], marker=MARKERS[method], label=LABELS[method], lw=1.4, ms=5)
            if method == REFERENCE_SEARCH:
                style.update(ls=":", lw=1.0, label="exhaustive (reference)")
            ax.plot([r["displacement"] for r in rows], [r[key] for r in rows], **style)
        ax.set_xlabel("displacement magnitude d (eight compass directions), px")
        ax.set_title(title)
        ax.set_xticks(list(cfg.int_displacements))
    axes[0].set_ylabel("search success rate, %")
    lows = [r[k] for r in block["rows"] for k in ("success_pct", "truth_pct")]
    axes[0].set_ylim(max(0.0, min(lows) - 5.0), 101.5)
    axes[1].legend(loc="lower left")
    n = block["rows"][0]["n"]
    fig.suptitle(f"Fig 9: integer-pixel search success rate, {_noise_title(sigma)}\n"
                 f"{n} points per displacement, subset {cfg.subset} px, search box +-{cfg.search_radius} px")
    fig.tight_layout()
    return fig


def _fig10(plt, blocks):
    methods = [m for m in SEARCHES + (REFERENCE_SEARCH,) if m in blocks[0]["cost"]]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    width = 0.8 / len(blocks)
    x = np.arange(len(methods))
    panels = (("time_ms_per_point", "time per point, ms", "(a) time"),
              ("evaluations", "distinct ZNCC evaluations per point", "(b) distinct ZNCC evaluations"),
              ("calls", "fitness calls per point (repeats included)", "(c) fitness calls"))
    for ax, (key, ylabel, title) in zip(axes, panels):
        for j, block in enumerate(blocks):
            sigma = block["rows"][0]["sigma"]
            values = [block["cost"][m][key] for m in methods]
            bars = ax.bar(x + (j - (len(blocks) - 1) / 2) * width, values, width,
                          color=[COLOURS[m] for m in methods], alpha=1.0 if sigma == 0 else 0.55,
                          hatch=None if sigma == 0 else "//", edgecolor="black", linewidth=0.5,
                          label="noise-free" if sigma == 0 else f"sigma = {sigma:g}")
            for bar, value in zip(bars, values):
                ax.annotate(f"{value:.3f}" if key.startswith("time") else f"{value:.0f}",
                            (bar.get_x() + bar.get_width() / 2, bar.get_height()), ha="center", va="bottom",
                            fontsize=6.5, rotation=90, xytext=(0, 2), textcoords="offset points")
        ax.set_xticks(x, [LABELS[m] for m in methods], rotation=20)
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.margins(y=0.2)
    _hatch_legend(axes[0], [block["rows"][0]["sigma"] for block in blocks])
    clean = blocks[0]["cost"]
    note = []
    for m in ("improved-wso",):
        if m in clean:
            for base in ("pso", "coarse-fine"):
                if f"time_vs_{base}" in clean[m]:
                    note.append(f"improved WSO time = {clean[m][f'time_vs_{base}']:.2f} x {LABELS[base]}")
    fig.suptitle("Fig 10: cost of the integer-pixel searches (same run as Fig 9; mean over all displacements)\n"
                 + ("; ".join(note) + " (noise-free)" if note else ""))
    fig.tight_layout()
    return fig


LOG_FLOOR = 1e-6


def _hatch_legend(ax, sigmas):
    from matplotlib.patches import Patch
    handles = [Patch(facecolor="0.6" if sigma == 0 else "0.85", edgecolor="black", hatch=None if sigma == 0 else "//",
                     label="noise-free" if sigma == 0 else f"noise sigma = {sigma:g}") for sigma in sigmas]
    ax.legend(handles=handles, loc="upper left")


def _fig11(plt, block, sigma):
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.4))
    for method in SUBPIXELS:
        rows = [r for r in block["rows"] if r["method"] == method and r["n"]]
        if not rows:
            continue
        s = np.array([r["displacement"] for r in rows])
        mean = np.array([r["mean_u"] for r in rows])
        sd = np.array([r["sd_u"] for r in rows])
        style = dict(color=COLOURS[method], marker=MARKERS[method], ms=4, lw=1.3, label=LABELS[method])
        axes[0].plot(s, mean, **style)
        # Log axes: exact zeros (e.g. an integer shift refined exactly) are left out.
        axes[1].plot(s, np.where(np.abs(mean) > 0, np.abs(mean), np.nan), **style)
        axes[2].plot(s, np.where(sd > 0, sd, np.nan), **style)
    noise = block.get("icgn_noise")
    if noise:
        s_noise = [r["displacement"] for r in noise["rows"]]
        axes[2].plot(s_noise, [r["predicted_sd"] for r in noise["rows"]], color="black", ls="--", lw=1.0,
                     label="IC-GN prediction, translation only:\nsqrt(2) sigma / sqrt(sum f_x^2)")
        axes[2].plot(s_noise, [r["predicted_first_order_sd"] for r in noise["rows"]], color="black", ls=":", lw=1.2,
                     label="IC-GN prediction, 1st-order shape:\nsqrt(2 sigma^2 [H^-1]_uu)")
    axes[0].axhline(0.0, color="black", lw=0.6)
    for ax in axes[1:]:
        ax.set_yscale("log")
        low, high = ax.get_ylim()
        ax.set_ylim(max(low, LOG_FLOOR), high)
    axes[0].set_ylabel("mean error of u, px")
    axes[1].set_ylabel("|mean error of u|, px (log)")
    axes[2].set_ylabel("standard deviation of u error, px (log)")
    axes[0].set_title("(a) mean error")
    axes[1].set_title(f"(a') |mean error|, log scale (below {LOG_FLOOR:g} px not shown)")
    axes[2].set_title(f"(b) standard deviation, log scale (below {LOG_FLOOR:g} px not shown)")
    for ax in axes:
        ax.set_xlabel("imposed displacement s (translation (s, 0)), px")
    handles, labels = axes[2].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=True)
    n = block["rows"][0]["n"] + block["rows"][0]["failed"]
    fig.suptitle(f"Fig 11: sub-pixel error vs displacement, {_noise_title(sigma)}\n"
                 f"{n} points per displacement, all methods started from the exhaustive integer argmax; "
                 "points whose status is not OK are left out (counts in the report)")
    fig.tight_layout(rect=(0, 0, 0.83, 1))
    return fig


def _fig07(plt, rows, sigma):
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for s, colour in zip(sorted({r["displacement"] for r in rows}), ("tab:blue", "tab:red", "tab:green")):
        mine = sorted((r for r in rows if r["displacement"] == s), key=lambda r: r["spacing"])
        h = [r["spacing"] for r in mine]
        axes[0].plot(h, [r["mean_u"] for r in mine], marker="o", color=colour, label=f"s = {s:g} px")
        axes[1].plot(h, [r["sd_u"] for r in mine], marker="o", color=colour, label=f"s = {s:g} px")
    axes[0].axhline(0.0, color="black", lw=0.6)
    axes[0].set_ylabel("mean error of u, px")
    axes[1].set_ylabel("standard deviation of u error, px")
    axes[0].set_title("(a) mean error")
    axes[1].set_title("(b) standard deviation")
    for ax in axes:
        ax.set_xlabel("fitting distance (lattice spacing) h, px")
        ax.legend()
    fig.suptitle(f"Fig 7: improved surface fit error vs fitting distance, {_noise_title(sigma)}")
    fig.tight_layout()
    return fig


PAPER_TABLE1_S = {"newton-raphson": 55.64, "gradient": 3.84, "surface-fit": 3.31, "improved-surface-fit": 1.95}


def table1_rows(results):
    stage = results.get("subpixel_clean")
    whole = results.get("measure_timing")
    nan = float("nan")
    rows = []
    for method in SUBPIXELS:
        row = dict(method=method)
        if stage and method in stage["stage_time_s"]:
            row["stage_s"] = stage["stage_time_s"][method]
            row["stage_us_per_point"] = stage["stage_us_per_point"][method]
            nr = stage["stage_time_s"].get("newton-raphson", nan)
            row["stage_pct_of_nr"] = 100.0 * stage["stage_time_s"][method] / nr
        if whole and method in whole["methods"]:
            entry = whole["methods"][method]
            row["measure_s"] = entry["time_s"]
            row["measure_us_per_point"] = entry["us_per_point"]
            nr = whole["methods"].get("newton-raphson", {}).get("time_s", nan)
            row["measure_pct_of_nr"] = 100.0 * entry["time_s"] / nr
        if method in PAPER_TABLE1_S:
            row["paper_s"] = PAPER_TABLE1_S[method]
            row["paper_pct_of_nr"] = 100.0 * PAPER_TABLE1_S[method] / PAPER_TABLE1_S["newton-raphson"]
        rows.append(row)
    return rows


def _table1(plt, rows):
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    x = np.arange(len(rows))
    series = (("stage_us_per_point", "measure_us_per_point"), ("stage_pct_of_nr", "measure_pct_of_nr", "paper_pct_of_nr"))
    names = {"stage_us_per_point": "sub-pixel stage alone", "measure_us_per_point": "whole measure() (improved WSO + method)",
             "stage_pct_of_nr": "sub-pixel stage alone", "measure_pct_of_nr": "whole measure()",
             "paper_pct_of_nr": "paper (Table 1)"}
    hatches = {"stage": None, "measure": "//", "paper": ".."}
    for ax, keys in zip(axes, series):
        width = 0.8 / len(keys)
        for j, key in enumerate(keys):
            values = [r.get(key, np.nan) for r in rows]
            bars = ax.bar(x + (j - (len(keys) - 1) / 2) * width, values, width, label=names[key],
                          hatch=hatches[key.split("_")[0]], edgecolor="black", linewidth=0.5,
                          color=["white" if key.startswith("paper") else COLOURS[r["method"]] for r in rows],
                          alpha=1.0 if key.startswith("stage") else 0.6)
            for bar, value in zip(bars, values):
                if np.isfinite(value):
                    ax.annotate(f"{value:.1f}" if "pct" in key and value < 10 else f"{value:.0f}",
                                (bar.get_x() + bar.get_width() / 2, bar.get_height()), ha="center", va="bottom",
                                fontsize=6.5)
        ax.set_xticks(x, [LABELS[r["method"]] for r in rows], rotation=15)
        ax.legend(fontsize=7, loc="upper left")
        ax.margins(y=0.3)
    axes[0].set_ylabel("time per point, microseconds")
    axes[0].set_title("(a) time per point")
    axes[1].set_ylabel("time relative to Newton-Raphson, %")
    axes[1].set_title("(b) time as % of Newton-Raphson (same run)")
    fig.suptitle("Table 1: computation time of the sub-pixel methods (noise-free Fig 11 job)")
    fig.tight_layout()
    return fig


def _fig12(plt, block):
    import matplotlib
    methods = [m for m in SUBPIXELS if m in block["u"]]
    axis = block["axis"]
    side = axis.size
    s = block["displacement"]
    values = np.concatenate([block["u"][m] for m in methods])
    finite = values[np.isfinite(values)]
    spread = float(np.percentile(np.abs(finite - s), 99.5)) if finite.size else 0.01
    spread = max(spread, 1e-3)
    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="0.25")
    fig, axes = plt.subplots(2, len(methods), figsize=(3.2 * len(methods) + 1.2, 7.2), squeeze=False,
                             layout="constrained")
    step = axis[1] - axis[0] if side > 1 else 1
    extent = (axis[0] - step / 2, axis[-1] + step / 2, axis[-1] + step / 2, axis[0] - step / 2)
    image = None
    for col, method in enumerate(methods):
        u = block["u"][method].reshape(side, side)
        err = u[np.isfinite(u)] - s
        bad = int((~np.isfinite(u)).sum())
        top, bottom = axes[0][col], axes[1][col]
        image = top.imshow(u, cmap=cmap, vmin=s - spread, vmax=s + spread, extent=extent, interpolation="nearest")
        top.set_title(f"{LABELS[method]}\nmean error {err.mean():+.4f}, SD {err.std():.4f} px"
                      + (f"\n{bad} point(s) not OK (dark grey)" if bad else ""), fontsize=8)
        own = max(float(np.max(np.abs(err))) if err.size else 0.0, 1e-6)
        mine = bottom.imshow(u - s, cmap=cmap, vmin=-own, vmax=own, extent=extent, interpolation="nearest")
        bottom.set_title(f"{LABELS[method]}: u - {s:g}, own scale", fontsize=8)
        fig.colorbar(mine, ax=bottom, shrink=0.8, pad=0.02, format="%.2g").set_label("u error, px")
        for ax in (top, bottom):
            ax.set_xlabel("x, px")
            ax.grid(False)
    axes[0][0].set_ylabel("y, px")
    axes[1][0].set_ylabel("y, px")
    bar = fig.colorbar(image, ax=list(axes[0]), shrink=0.85, pad=0.01)
    bar.set_label(f"u, px (true {s:g}); common scale")
    fig.suptitle(f"Fig 12: u field at translation ({s:g}, 0) px, {_noise_title(block['sigma'])}; "
                 f"{side} x {side} points. Top: common colour scale; bottom: each method's error on its own scale")
    return fig


def _fig_radius(plt, summary):
    """Success (all generators and noise levels pooled) and evaluations per point against the search radius."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    for method in RADIUS_SEARCHES:
        rows = [r for r in summary if r["method"] == method]
        if not rows:
            continue
        radii = [r["radius"] for r in rows]
        style = dict(color=COLOURS.get(method, "k"), marker=MARKERS.get(method, "o"), label=RADIUS_LABELS[method])
        left.plot(radii, [r["success_pct"] for r in rows], **style)
        right.plot(radii, [r["evaluations"] for r in rows], **style)
    left.set_xlabel("search radius (px)")
    left.set_ylabel("success (% same integer as exhaustive)")
    left.set_title("integer search success vs radius")
    right.set_xlabel("search radius (px)")
    right.set_ylabel("distinct ZNCC evaluations per point")
    right.set_yscale("log")
    right.set_title("cost vs radius")
    right.legend(loc="upper left")
    fig.suptitle("all generators (simulator R = 2, 4, 5, FFT noise, sparse dots, discs), noise-free and sigma = 2")
    return fig
