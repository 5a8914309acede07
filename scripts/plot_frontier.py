#!/usr/bin/python3
"""Draws fulgur-study frontier's CSV: error against the truth versus cost, with the Pareto front.

usage: scripts/plot_frontier.py STUDY_DIR [OUT_PREFIX]

Reads STUDY_DIR/frontier.csv (one row per configuration) and writes OUT_PREFIX.png and
OUT_PREFIX.svg (default: docs/images/frontier). Left: worst error over the strikes (relative L2
of S over cloud voxels against the truth) versus the frame's cost amortized over the 60 frames
between strikes (the frame's own time plus the strike's solve / 60), log scale. Right: the same
error versus bake time. The Pareto front (no configuration both cheaper and more accurate) is
drawn on each. Uses Debian's python3-matplotlib (run with /usr/bin/python3).
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
    "reference": ("D", "tab:red"),
}


def pareto(points):
    """Indices of the points on the lower-left front (cost, error), sorted by cost."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], float("inf")
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def panel(ax, rows, cost_key, xlabel):
    pts = [(float(r[cost_key]), float(r["error_vs_truth"])) for r in rows]
    for r, (x, y) in zip(rows, pts):
        marker, colour = PRESET_STYLE.get(r["preset"], ("x", "black"))
        ax.scatter(x, 100 * y, marker=marker, color=colour, s=46, zorder=3)
        ax.annotate(r["config"], (x, 100 * y), textcoords="offset points", xytext=(5, 4), fontsize=7)
    front = pareto(pts)
    ax.plot([pts[i][0] for i in front], [100 * pts[i][1] for i in front], color="0.4", lw=1.2, ls="--",
            zorder=2, label="Pareto front")
    ax.set_xscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("worst error against the truth (% relative L2 of S)")
    ax.grid(True, which="both", color="0.9")
    ax.set_ylim(bottom=0)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    study = Path(sys.argv[1])
    out = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(__file__).resolve().parent.parent / "docs/images/frontier"
    with open(study / "frontier.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit(f"{study / 'frontier.csv'}: no rows")
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    panel(axes[0], rows, "amortized_frame_ms", "frame cost, ms (frame + strike solve / 60 frames), log")
    panel(axes[1], rows, "bake_s", "bake time, s (log)")
    handles = [plt.Line2D([], [], marker=m, color=c, ls="", label=p) for p, (m, c) in PRESET_STYLE.items()]
    handles.append(plt.Line2D([], [], color="0.4", ls="--", label="Pareto front"))
    strikes = len({r["seed"] for r in csv.DictReader(open(study / "frontier_strikes.csv", newline=""))})
    fig.suptitle(f"Default storm, {strikes} strikes: what accuracy costs", y=0.985)
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.945), ncol=len(handles), frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.89))
    out.parent.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "svg"):
        fig.savefig(f"{out}.{ext}", dpi=130)
    print(f"wrote {out}.png and {out}.svg")


if __name__ == "__main__":
    main()
