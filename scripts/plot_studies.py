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
  lb_convergence.csv -> lb_convergence.{png,svg}: the sun-lit lattice's total density per site
                      and its relative change per step (log), against 2N steps.
  lb_vs_mc_profile.csv -> lb_vs_mc_profile.{png,svg}: S in the light's column against height,
                      Monte Carlo and the lattice's variants (log).
  runtime_accuracy.csv -> runtime_accuracy.{png,svg}: the basis method against the direct solve
                      per strike, split into splat and basis errors (log).
  runtime_accuracy_spacing.csv -> runtime_accuracy_spacing.{png,svg}: the splat's error against
                      the virtual-light spacing (log-log).
  latency_summary.csv -> latency.{png,svg}: each preset's worst-strike error against the truth
                      versus wall time since an unscheduled strike became known, one panel per
                      scene, the targets dotted.
  static_frontier.csv (+ static_sky.csv) -> static_frontier.{png,svg}: the static light's worst
                      total and multiple-scattering error against its truth versus solve time,
                      one panel per scene: the sun's configurations (worst of its elevations)
                      and the sky dome's configurations (directions or the dome's Monte Carlo; the
                      scene's sky), the aims dotted.
  near_field.csv   -> near_field.{png,svg}: the splat with a near-field correction, worst strike's
                      error against the truth versus the correction's time (one thread, the
                      slowest strike) per model and ray count, one panel per scene; the paper
                      frame, perfect bases with the corrections and the 20% first-frame aim as
                      lines.
Run with /usr/bin/python3 (Debian's matplotlib lives there).
"""
import csv
import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402

PRESET_STYLE = {
    "paper": ("o", "tab:blue"),
    "hybrid": ("s", "tab:orange"),
    "per_strike": ("^", "tab:green"),
    "per_strike_mc": ("v", "tab:purple"),
    "instant": ("*", "tab:brown"),
    "instant_no_near_field": ("x", "tab:gray"),
    "instant_kernel": ("P", "tab:olive"),
    "instant_128": ("h", "tab:cyan"),
    "instant_lighting_single": ("p", "tab:pink"),
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


def finish_single(fig, ax, title, out_dir, name, plain_ticks=()):
    """Grid, legend outside the data on the right, title, and save; `plain_ticks` lists the
    log axes ("x", "y") whose ticks read as plain numbers (5, 10, 50) instead of powers of 10."""
    for axis in plain_ticks:
        plain = matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}")
        getattr(ax, axis + "axis").set_major_formatter(plain)
        getattr(ax, axis + "axis").set_minor_formatter(matplotlib.ticker.NullFormatter())
        if axis == "y" and ax.get_yscale() == "log":  # 5, 10, 20, 50, 100: ticks on a short span
            ax.yaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.grid(True, which="both" if plain_ticks else "major", color="0.9")
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False, fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    save(fig, out_dir, name)


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


# --- lattice convergence -----------------------------------------------------------------


def plot_lb_convergence(study, out_dir):
    with open(study / "lb_convergence.csv", newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        data = [[float(v) for v in row] for row in reader]
    steps = [row[0] for row in data]
    two_n = None
    summary = study / "lb_convergence_summary.csv"
    if summary.exists():
        two_n = float(read(summary)[0]["two_N"])
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
    ymax = 0.0
    for k, label in enumerate(header[1:], start=1):
        ys = [row[k] for row in data]
        style = "--" if "0.85" in label else "-"
        axes[0].plot(steps, ys, style, lw=1.3, label=label)
        if "published" not in label:  # the published collision may blow up: keep the others readable
            ymax = max([ymax] + [y for y in ys if math.isfinite(y)])
        change = [abs(ys[t] - ys[t - 2]) / (2 * abs(ys[t])) if t >= 2 and ys[t] else float("nan") for t in range(len(ys))]
        axes[1].plot(steps, change, style, lw=1.1, label=label)
    axes[0].set_ylim(0, 1.15 * ymax)
    axes[0].set_ylabel("total lattice density per site")
    axes[1].set_yscale("log")
    axes[1].set_ylim(bottom=1e-8)
    axes[1].axhline(1e-4, color="tab:red", lw=0.8, ls=":")
    axes[1].annotate("default tolerance 1e-4", (steps[-1], 1e-4), textcoords="offset points", xytext=(-120, 4),
                     fontsize=8, color="tab:red")
    axes[1].set_ylabel("|M(t) - M(t-2)| / 2M(t)")
    for ax in axes:
        ax.set_xlabel("lattice step")
        ax.set_xlim(left=0)
        ax.grid(True, which="major", color="0.9")
        if two_n:
            ax.axvline(two_n, color="0.5", lw=0.8, ls="--")
            ax.annotate("2N", (two_n, ax.get_ylim()[1]), textcoords="offset points", xytext=(3, -12), fontsize=8)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.93), ncol=3, frameon=False, fontsize=8)
    fig.suptitle("Sun-lit lattice on the study cloud: convergence (cf. Geist 2004, Fig. 5)", y=0.99)
    fig.tight_layout(rect=(0, 0, 1, 0.87))
    save(fig, out_dir, "lb_convergence")


# --- S in the light's column ---------------------------------------------------------------


def plot_lb_vs_mc_profile(study, out_dir):
    rows = read(study / "lb_vs_mc_profile.csv")
    z = [float(r["z_m"]) / 1000 for r in rows]
    cloud = [float(r["density"]) > 0 for r in rows]
    base = min((zz for zz, c in zip(z, cloud) if c), default=None)
    fig, ax = plt.subplots(figsize=(9, 5.2))

    def col(name):
        return [float(r[name]) if c else float("nan") for r, c in zip(rows, cloud)]

    mc1, mcm, s1 = col("mc_single"), col("mc_multiple"), col("S1")
    ax.plot(z, [a + b for a, b in zip(mc1, mcm)], "o-", color="black", ms=3, label="Monte Carlo total")
    ax.plot(z, mcm, "o-", color="0.5", ms=3, label="Monte Carlo multiple")
    ax.plot(z, s1, "--", color="tab:blue", label="exact single S1")
    for name, colour, label in (("lb_multiple_physical", "tab:red", "physical"),
                                ("lb_multiple_conservative", "tab:green", "conservative")):
        ax.plot(z, [a + b for a, b in zip(s1, col(name))], "-", color=colour, label=f"S1 + LB {label}")
    ax.plot(z, col("lb_multiple_physical"), ":", color="tab:red", label="LB physical multiple")
    extra = [k for k in rows[0] if k.startswith("lb_multiple_physical_")]
    for name, colour in zip(extra, ("tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive")):
        ax.plot(z, col(name), ":", lw=1.4, color=colour,
                label="LB physical multiple, " + name[len("lb_multiple_physical_"):].replace("_", " "))
    ax.set_yscale("log")
    ax.set_ylim(bottom=1e-11)  # S1 falls to ~1e-20 at the top: keep the multiple scattering readable
    if base is not None:
        ax.axvline(base, color="0.5", lw=0.8, ls="--")
        ax.annotate("lowest cloud voxel", (base, 1e-11), textcoords="offset points", xytext=(3, 6), fontsize=8)
    ax.set_xlabel("height (km)")
    ax.set_ylabel("S, mean over directions (W m$^{-2}$ sr$^{-1}$)")
    finish_single(fig, ax, "S in the light's column (default storm, 500 m voxels)", out_dir, "lb_vs_mc_profile")


# --- the basis method against the direct solve ----------------------------------------------


def plot_runtime_accuracy(study, out_dir):
    rows = read(study / "runtime_accuracy.csv")
    seeds = [int(float(r["seed"])) for r in rows]
    fig, ax = plt.subplots(figsize=(9, 4.8))
    for key, label, style in (("err_single", "single scattering", "s--"),
                              ("err_multiple", "multiple scattering", "^--"),
                              ("splat_V_vs_D", "splat (virtual lights vs sources, both solved directly)", "D-"),
                              ("basis_R_vs_V", "basis (reconstruction vs virtual lights solved directly)", "v:")):
        ax.plot(seeds, [100 * float(r[key]) for r in rows], style, label=label)
    # The total last, hollow, over the splat it nearly equals.
    ax.plot(seeds, [100 * float(r["err_total"]) for r in rows], "o-", color="black", mfc="none", ms=9, lw=0.8,
            label="total", zorder=4)
    ax.set_yscale("log")
    ax.axhline(5, color="tab:red", lw=0.8, ls=":")
    ax.annotate("aim 5%", (seeds[0], 5), textcoords="offset points", xytext=(2, 3), fontsize=8, color="tab:red")
    ax.set_xticks(seeds)
    ax.set_xlabel("strike (seed)")
    ax.set_ylabel("relative L2 error of S over the cloud (%)")
    finish_single(fig, ax, "Basis method against the direct solve, default storm, return stroke", out_dir,
                  "runtime_accuracy", plain_ticks=("y",))


def plot_runtime_accuracy_spacing(study, out_dir):
    rows = read(study / "runtime_accuracy_spacing.csv")
    fig, ax = plt.subplots(figsize=(9, 4.8))
    for seed in dict.fromkeys(r["seed"] for r in rows):
        sel = [r for r in rows if r["seed"] == seed]
        ax.plot([float(r["h_usr"]) for r in sel], [100 * float(r["splat_total"]) for r in sel], "o-",
                label=f"strike {int(float(seed))}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.axhline(5, color="tab:red", lw=0.8, ls=":")
    ax.annotate("aim 5%", (min(float(r["h_usr"]) for r in rows), 5), textcoords="offset points", xytext=(2, 3),
                fontsize=8, color="tab:red")
    for key, text in (("scene_h_usr", "scene's h_usr"), ("lighting_voxel_m", "lighting voxel")):
        if key in rows[0]:
            x = float(rows[0][key])
            ax.axvline(x, color="0.5", lw=0.8, ls="--")
            ax.annotate(text, (x, ax.get_ylim()[1]), textcoords="offset points", xytext=(3, -12), fontsize=8)
    ax.set_xticks(sorted({float(r["h_usr"]) for r in rows}))  # the spacings measured
    ax.set_xlabel("virtual-light spacing h_usr (m)")
    ax.set_ylabel("splat error: relative L2 of S over the cloud (%)")
    finish_single(fig, ax, "Splat error against virtual-light spacing (lights solved directly, no compression)",
                  out_dir, "runtime_accuracy_spacing", plain_ticks=("x", "y"))


# --- latency ------------------------------------------------------------------------------


def worst_strike_panel(ax, scene, xlabel):
    """Labels and grid of a panel of one scene's worst-strike error against the truth."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel("worst strike: S error against the truth, %")
    ax.set_title(scene)
    ax.grid(True, which="both", color="0.9")


def finish_panels(fig, axes, title, out_dir, name):
    """One legend right of the last panel, the title, and save."""
    axes[0][-1].legend(loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False, fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    save(fig, out_dir, name)


def plot_latency(study, out_dir):
    rows = read(study / "latency_summary.csv")
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.2 * len(scenes) + 1.5, 3.8), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        mine = [r for r in rows if r["scene"] == scene]
        for preset in dict.fromkeys(r["preset"] for r in mine):
            pts = sorted((float(r["since_known_ms"]), 100.0 * float(r["worst_error"]))
                         for r in mine if r["preset"] == preset)
            # 0 ms on a log axis: drawn at 5 ms, the axis says so.
            xs = [max(x, 5.0) for x, _ in pts]
            marker, colour = PRESET_STYLE.get(preset, ("x", "0.3"))
            ax.plot(xs, [y for _, y in pts], marker=marker, color=colour, label=preset)
        for ms, pct in ((5.0, 20.0), (100.0, 10.0), (300.0, 7.0)):
            ax.plot([ms], [pct], marker="_", markersize=18, color="0.4")
        ax.set_xscale("log")
        ax.set_yscale("log")
        worst_strike_panel(ax, scene, "ms since the strike became known (0 drawn at 5)")
    finish_panels(fig, axes, "Unscheduled strikes: error against time (grey bars: the targets 20% / 10% / 7%)",
                  out_dir, "latency")


# --- static light against its truth ------------------------------------------------------


def plot_static_frontier(study, out_dir):
    sun = read(study / "static_frontier.csv")
    sky = read(study / "static_sky.csv") if (study / "static_sky.csv").exists() else []
    scenes = list(dict.fromkeys([r["scene"] for r in sun] + [r["scene"] for r in sky]))
    fig, axes = plt.subplots(1, len(scenes), figsize=(6.5 * len(scenes), 5), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        configs = {}
        for r in sun:  # the worst of the sun's elevations per configuration
            if r["scene"] != scene:
                continue
            c = configs.setdefault(r["config"], [0.0, 0.0, 0.0])
            c[0] = max(c[0], float(r["seconds"]))
            c[1] = max(c[1], 100 * float(r["total_error"]))
            c[2] = max(c[2], 100 * float(r["multiple_error"]))
        for name, (x, total, multiple) in configs.items():
            ax.scatter(x, total, marker="o", color="tab:orange", s=40, zorder=3)
            ax.scatter(x, multiple, marker="^", color="tab:orange", s=30, zorder=3, alpha=0.55)
            ax.annotate("sun " + name, (x, total), textcoords="offset points", xytext=(5, 3), fontsize=7)
        for r in sky:
            if r["scene"] != scene or r["basis"] not in ("scene", "uniform"):
                continue
            x = float(r["seconds"])
            ax.scatter(x, 100 * float(r["total_error"]), marker="s", color="tab:blue", s=40, zorder=3)
            ax.scatter(x, 100 * float(r["multiple_error"]), marker="^", color="tab:blue", s=30, zorder=3, alpha=0.55)
            paths = int(float(r.get("paths", "0") or 0))
            label = f"sky MC {paths / 1e6:g}M" if paths else f"sky {r['samples']} dirs"
            ax.annotate(label, (x, 100 * float(r["total_error"])), textcoords="offset points", xytext=(5, 3),
                        fontsize=7)
        for y, text in ((10, "total 10%"), (15, "multiple 15%")):
            ax.axhline(y, color="tab:red", lw=0.8, ls=":")
            ax.annotate(text, (ax.get_xlim()[0], y), textcoords="offset points", xytext=(3, 2), fontsize=7,
                        color="tab:red")
        ax.set_xscale("log")
        ax.set_xlabel("solve time, s (2 threads, log)")
        ax.set_ylabel("error against the truth, % (relative L2 of S)")
        ax.set_title(scene)
        ax.grid(True, which="both", color="0.9")
        ax.set_ylim(bottom=0)
    handles = [plt.Line2D([], [], marker="o", color="tab:orange", ls="", label="sun: total (worst elevation)"),
               plt.Line2D([], [], marker="s", color="tab:blue", ls="", label="sky (the scene's): total"),
               plt.Line2D([], [], marker="^", color="0.5", ls="", label="multiple scattering")]
    fig.suptitle("The static light: what accuracy costs", y=0.985)
    fig.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.94), ncol=3, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.88))
    save(fig, out_dir, "static_frontier")


# --- near-field correction of the splat -----------------------------------------------------


def plot_near_field(study, out_dir):
    rows = read(study / "near_field.csv")
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes) + 2.5, 4.4), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        worst = {}  # candidate -> rays -> [worst total, slowest seconds]
        for r in rows:
            if r["scene"] != scene:
                continue
            w = worst.setdefault(r["candidate"], {}).setdefault(int(float(r["rays"])), [0.0, 0.0])
            w[0] = max(w[0], 100 * float(r["total_error"]))
            w[1] = max(w[1], float(r["seconds"]))
        colours = iter(("tab:orange", "tab:green", "tab:olive", "tab:purple", "tab:pink", "tab:cyan", "tab:brown"))
        lines = iter(("--", "-.", ":", (0, (5, 1))))
        for name, by_rays in worst.items():
            if 0 in by_rays:  # no correction, or perfect bases: no time of its own
                ax.axhline(by_rays[0][0], color="tab:blue" if name == "paper" else "0.5", lw=1.0, ls="-")
                ax.annotate(name, (2e-3, by_rays[0][0]), textcoords="offset points",
                            xytext=(2, 3) if name == "paper" else (2, -10), fontsize=7)
            elif name.startswith("perfect bases"):
                (_, (err, _)), = by_rays.items()
                ax.axhline(err, color="0.5", lw=1.0, ls=next(lines), label=name)
            else:
                pts = sorted((s, e, n) for n, (e, s) in by_rays.items())
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", color=next(colours), label=name)
                for s, e, n in pts:
                    ax.annotate(f"{n}", (s, e), textcoords="offset points", xytext=(3, 3), fontsize=6)
        ax.axhline(20, color="tab:red", lw=0.8, ls=":")
        ax.annotate("first-frame aim 20%", (2e-3, 20), textcoords="offset points", xytext=(2, -10), fontsize=7,
                    color="tab:red")
        ax.set_xscale("log")
        ax.set_xlim(left=1e-3)
        ax.set_ylim(bottom=0)
        worst_strike_panel(ax, scene, "correction time, s (slowest strike; one thread, the engine's two;\n"
                                      "labels: rays per point)")
    finish_panels(fig, axes, "The splat with a near-field correction", out_dir, "near_field")


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    study = Path(sys.argv[1])
    out_dir = Path(sys.argv[2]) if len(sys.argv) > 2 else Path(__file__).resolve().parent.parent / "docs/images"
    drawn = 0
    tables = (("frontier.csv", plot_frontier), ("lb_vs_truth.csv", plot_lb_vs_truth),
              ("lb_convergence.csv", plot_lb_convergence), ("lb_vs_mc_profile.csv", plot_lb_vs_mc_profile),
              ("runtime_accuracy.csv", plot_runtime_accuracy),
              ("runtime_accuracy_spacing.csv", plot_runtime_accuracy_spacing),
              ("latency_summary.csv", plot_latency), ("static_frontier.csv", plot_static_frontier),
              ("near_field.csv", plot_near_field))
    for name, fn in tables:
        if (study / name).exists():
            fn(study, out_dir)
            drawn += 1
    if drawn == 0:
        sys.exit(f"{study}: no table this script draws ({', '.join(name for name, _ in tables)})")


if __name__ == "__main__":
    main()
