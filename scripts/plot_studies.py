#!/usr/bin/python3
"""Draws the CSV tables fulgur-study writes, with Debian's python3-matplotlib.

usage: scripts/plot_studies.py STUDY_DIR [OUT_DIR]

For each table found in STUDY_DIR it writes a PNG (for the README) and an SVG (for docs/) into
OUT_DIR (default: docs/images):
  frontier.csv     -> frontier.{png,svg}: worst error against the truth versus the frame's cost
                      (frame + strike solve amortized over the 60 frames between strikes) and
                      versus bake time, one marker per configuration, the Pareto front dashed.
  lb_vs_truth.csv  -> lb_vs_truth.{png,svg}: the lattice's multiple-scattering error and ratio
                      of totals against the truth per light and lattice, and per band of hop
                      optical depth.
Run with /usr/bin/python3 (Debian's matplotlib lives there).
"""
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PRESET_STYLE = {
    "paper": ("o", "tab:blue"),
    "hybrid": ("s", "tab:orange"),
    "per_strike": ("^", "tab:green"),
    "per_strike_mc": ("v", "tab:purple"),
    "reference": ("D", "tab:red"),
}


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def save(fig, out_dir, name):
    out_dir.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "svg"):
        fig.savefig(out_dir / f"{name}.{ext}", dpi=130)
    plt.close(fig)
    print(f"wrote {out_dir / name}.png and .svg")


# --- frontier -----------------------------------------------------------------------------


def pareto(points):
    """Indices of the points on the lower-left front (cost, error), sorted by cost."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], float("inf")
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def frontier_panel(ax, rows, cost_key, xlabel, targets=()):
    """One marker per configuration; the Pareto front dashed and its points named (the others
    would bury each other's labels: the CSV names every point)."""
    pts = [(float(r[cost_key]), float(r["error_vs_truth"])) for r in rows]
    front = pareto(pts)
    for i, (r, (x, y)) in enumerate(zip(rows, pts)):
        marker, colour = PRESET_STYLE.get(r["preset"], ("x", "black"))
        ax.scatter(x, 100 * y, marker=marker, color=colour, s=46, zorder=3, alpha=1.0 if i in front else 0.45)
        if i in front or r["config"] in PRESET_STYLE:
            ax.annotate(r["config"], (x, 100 * y), textcoords="offset points", xytext=(5, 4), fontsize=7)
    ax.plot([pts[i][0] for i in front], [100 * pts[i][1] for i in front], color="0.4", lw=1.2, ls="--", zorder=2)
    for x, y, text in targets:  # the aims: error at most y at a cost of at most x
        ax.plot([ax.get_xlim()[0] if x is None else x] * 2, [0, y], color="tab:red", lw=0.8, ls=":")
        ax.axhline(y, color="tab:red", lw=0.8, ls=":")
        ax.annotate(text, (x, y), textcoords="offset points", xytext=(3, -10), fontsize=7, color="tab:red")
    ax.set_xscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("worst error against the truth (% relative L2 of S)")
    ax.grid(True, which="both", color="0.9")
    ax.set_ylim(bottom=0)


def plot_frontier(study, out_dir):
    rows = read(study / "frontier.csv")
    strikes = len({r["seed"] for r in read(study / "frontier_strikes.csv")})
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    frontier_panel(axes[0], rows, "amortized_frame_ms", "frame cost, ms (frame + strike solve / 60 frames), log",
                   [(2.0, 20.0, "20% at 2 ms"), (16.0, 10.0, "10% at 16 ms")])
    frontier_panel(axes[1], rows, "bake_s", "bake time, s (log)", [(300.0, 20.0, "bake 5 min")])
    handles = [plt.Line2D([], [], marker=m, color=c, ls="", label=p) for p, (m, c) in PRESET_STYLE.items()]
    handles.append(plt.Line2D([], [], color="0.4", ls="--", label="Pareto front"))
    fig.suptitle(f"Default storm, {strikes} strikes: what accuracy costs", y=0.985)
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.945), ncol=len(handles), frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.89))
    save(fig, out_dir, "frontier")


# --- lattice against the truth ------------------------------------------------------------


def plot_lb_vs_truth(study, out_dir):
    rows = read(study / "lb_vs_truth.csv")
    lights = list(dict.fromkeys(r["light"] for r in rows))
    lattices = list(dict.fromkeys(r["lattice"] for r in rows))
    bands = [b for b in dict.fromkeys(r["band"] for r in rows) if b != "all"]
    table = {(r["light"], r["lattice"], r["band"]): r for r in rows}
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    width = 0.8 / len(lattices)
    for k, lattice in enumerate(lattices):
        xs = [i + (k - (len(lattices) - 1) / 2) * width for i in range(len(lights))]
        err = [100 * float(table[(l, lattice, "all")]["error_multiple"]) for l in lights]
        ratio = [float(table[(l, lattice, "all")]["ratio_multiple"]) for l in lights]
        axes[0].bar(xs, err, width, label=lattice)
        axes[1].bar(xs, ratio, width, label=lattice)
        band_err = []
        for band in bands:
            vals = [float(table[(l, lattice, band)]["error_multiple"]) for l in lights if (l, lattice, band) in table]
            band_err.append(100 * max(vals) if vals else float("nan"))
        axes[2].plot(bands, band_err, marker="o", label=lattice)
    for ax in axes[:2]:
        ax.set_xticks(range(len(lights)))
        ax.set_xticklabels([f"light {l}" for l in lights])
    axes[0].set_ylabel("orders >= 2: relative L2 against the truth (%)")
    axes[0].axhline(15, color="0.5", ls="--", lw=1)
    axes[0].annotate("15%", (len(lights) - 0.5, 15), textcoords="offset points", xytext=(2, 2), fontsize=8)
    axes[1].set_ylabel("orders >= 2: sum lattice / sum truth")
    axes[1].axhspan(0.9, 1.1, color="0.92", zorder=0)
    axes[2].set_ylabel("orders >= 2: worst light's relative L2 (%)")
    axes[2].set_xlabel("hop optical depth of the lighting voxel")
    for ax in axes:
        ax.grid(True, axis="y", color="0.9")
    handles, labels = axes[0].get_legend_handles_labels()
    ncol = min(4, len(labels))
    rows = (len(labels) + ncol - 1) // ncol
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.95), ncol=ncol, frameon=False)
    fig.suptitle("Lattice-Boltzmann against the truth, one light at a time (default storm, 750 m lighting grid)",
                 y=0.995)
    fig.tight_layout(rect=(0, 0, 1, 0.9 - 0.05 * rows))
    save(fig, out_dir, "lb_vs_truth")


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    study = Path(sys.argv[1])
    out_dir = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(__file__).resolve().parent.parent / "docs/images"
    drawn = 0
    for name, fn in (("frontier.csv", plot_frontier), ("lb_vs_truth.csv", plot_lb_vs_truth)):
        if (study / name).exists():
            fn(study, out_dir)
            drawn += 1
    if drawn == 0:
        sys.exit(f"{study}: no table this script draws (frontier.csv, lb_vs_truth.csv)")


if __name__ == "__main__":
    main()
