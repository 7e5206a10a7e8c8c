"""The files of ``livedic bench strain``: a CSV per table and ``strain.png``."""

import csv

import numpy as np

from livedic.bench.strain.uniform import GENERATORS, STRAIN_CASES, TARGET_RMS, TARGET_VSG_PX

def _cell(value):
    if isinstance(value, (bool, np.bool_)):
        return int(value)                    # ok columns are 1/0, as in livedic's other CSVs
    if isinstance(value, float):
        return f"{value:.9g}"
    return value


def write_csv(path, rows):
    """``rows`` (dicts with the same keys) as a CSV with a header; nothing for no rows."""
    if not rows:
        return None
    keys = list(rows[0])
    for row in rows[1:]:
        keys.extend(k for k in row if k not in keys)
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=keys)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(v) for k, v in row.items()})
    return path


def draw(path, uniform, tensile, dogbone):
    """``strain.png``: RMS vs VSG, the tensile e_yy profile, extensometer errors, the dog-bone readings."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = 4 if dogbone else 3
    fig, axes = plt.subplots(1, panels, figsize=(5.2 * panels, 4.4))
    ax = axes[0]
    for generator, style in zip(GENERATORS, ("-", "--")):
        for case, _ in STRAIN_CASES:
            mine = [r for r in uniform if r["generator"] == generator and r["case"] == case and r["subset"] == 21]
            ax.semilogy([r["vsg_px"] for r in mine], [r["rms_max"] for r in mine], style, marker="o", ms=3,
                        label=f"{generator}, {case}")
    ax.axhline(TARGET_RMS, color="k", lw=0.8)
    ax.axvline(TARGET_VSG_PX, color="k", lw=0.8, ls=":")
    ax.set(xlabel="VSG (px), subset 21, step 5", ylabel="strain error RMS (worst of exx, eyy, exy)",
           title="a. uniform strain, 8-bit, noise 1")
    ax.legend(fontsize=6)
    ax = axes[1]
    last = tensile["last"]
    if last is not None:
        order = np.argsort(last["y"])
        ax.plot(last["y"][last["ok"]], last["eyy"][last["ok"]], ".", ms=2, label="measured (default window)")
        ax.plot(last["y"][order], last["exact"][order], "k-", lw=1, label="exact dV/dY")
        y_neck, width = tensile["neck"]
        ax.axvspan(y_neck - width, y_neck + width, color="0.9", label="neck")
    ax.set(xlabel="reference Y (px)", ylabel="e_yy", title=f"b. tensile test, last frame, VSG {tensile['vsg_px']:g} px")
    ax.legend(fontsize=7)
    ax = axes[2]
    for name in tensile["summary"]:
        mine = [r for r in tensile["extensometer_rows"] if r["name"] == name]
        ax.plot([r["frame"] for r in mine], [r["error"] / r["tolerance"] for r in mine],
                label=f"{name}, L0 {mine[0]['L0_px']:.0f} px")
    for level in (-1.0, 1.0):
        ax.axhline(level, color="k", lw=0.8, ls=":")
    ax.set(xlabel="frame", ylabel="error / (50 microstrain + 0.5 % of reading)",
           title="b. extensometers vs exact (ISO 9513 class 0.5)")
    ax.legend(fontsize=7)
    if dogbone:
        ax = axes[3]
        rows = dogbone["rows"]
        k = np.arange(len(rows))
        ax.plot(k, [100 * r["axial_true"] for r in rows], "o-", ms=3, label="livedic axial (true)")
        ax.plot(k, [100 * r["mudic_gauge_true"] for r in rows], "s--", ms=3, label="muDIC, same gauge")
        ax.plot(k, [100 * r["mudic_mean_true_eyy"] for r in rows], "^:", ms=3, label="muDIC mean over mesh")
        ax.set(xlabel="frame (every 5th)", ylabel="true strain (%)", title="c. real dog-bone")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
