#!/usr/bin/python3
"""Draws the frame times of `voxshadow bench --loop --csv` (one panel per backend): the incremental frames as a
line, the forced full frames as points, the phases shaded. Usage: plot_loop.py LOOP.csv OUT.png

`voxshadow bench --loop --plot OUT.png` runs it; it needs Debian's python3-matplotlib.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")  # no display: a file is all that is wanted
import matplotlib.pyplot as plt  # noqa: E402

PHASES = ["still", "pan", "actor", "dig", "sun"]
SHADES = ["#f2f2f2", "#e3ecf7", "#eaf5e4", "#f7eadf", "#f5e4ef"]


def main(argv):
    if len(argv) != 3:
        sys.stderr.write("usage: plot_loop.py LOOP.csv OUT.png\n")
        return 2
    rows = []
    with open(argv[1], newline="") as f:
        for r in csv.DictReader(f):
            rows.append(r)
    backends = []
    for r in rows:
        if r["backend"] not in backends:
            backends.append(r["backend"])
    if not backends:
        sys.stderr.write("plot_loop.py: %s has no frames\n" % argv[1])
        return 1

    fig, axes = plt.subplots(len(backends), 1, figsize=(12, 3.6 * len(backends)), squeeze=False, sharex=True)
    for ax, backend in zip(axes[:, 0], backends):
        mine = [r for r in rows if r["backend"] == backend]
        frames = {p: 1 + max((int(r["frame"]) for r in mine if r["phase"] == p), default=-1) for p in PHASES}
        start, x = 0, {}
        for p in PHASES:
            x[p] = start
            start += frames[p]
        inc = [(x[r["phase"]] + int(r["frame"]), float(r["ms"])) for r in mine if r["kind"] == "incremental"]
        full = [(x[r["phase"]] + int(r["frame"]), float(r["ms"])) for r in mine if r["kind"] == "full"]
        for i, p in enumerate(PHASES):
            if frames[p] == 0:
                continue
            ax.axvspan(x[p] - 0.5, x[p] + frames[p] - 0.5, color=SHADES[i], zorder=0)
            ax.text(x[p] + frames[p] / 2.0 - 0.5, 1.0, p, transform=ax.get_xaxis_transform(), ha="center",
                    va="bottom", fontsize=9)
        if inc:
            ax.plot([a for a, _ in inc], [b for _, b in inc], "-", lw=1.2, color="#1f5fa8", label="incremental frame",
                    zorder=2)
        if full:
            ax.plot([a for a, _ in full], [b for _, b in full], "o", ms=3.5, color="#c0392b",
                    label="forced full frame", zorder=3)
        ax.set_yscale("log")
        ax.set_ylabel("%s: ms per frame" % backend)
        ax.grid(True, which="both", axis="y", alpha=0.3)
        ax.legend(loc="lower right", fontsize=8)
    axes[-1, 0].set_xlabel("frame (phases in order)")
    fig.suptitle("voxshadow bench --loop: frame time, incremental and forced full", y=0.995)
    fig.tight_layout()
    fig.savefig(argv[2], format="png", dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
