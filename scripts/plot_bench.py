#!/usr/bin/env python3
"""Plots for scripts/bench_peers.sh from the .tsv files peers_bench writes into a report folder.

Usage: scripts/plot_bench.py DIR
Writes DIR/pages_<scene>.png (cold pages read per query against box side, one line per engine, with
mktree's I/O floor), DIR/build_throughput.png (objects/s against N for the tanker scenes) and prints
Markdown that links them (appended to REPORT.md by the script).
"""
import glob
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(d):
    builds = []  # (scene, n, engine, objects_per_s)
    queries = defaultdict(lambda: defaultdict(list))  # scene -> engine -> [(frac, side, pages, floor, cold_qps)]
    sizes = {}
    for path in sorted(glob.glob(os.path.join(d, "*.tsv"))):
        for line in open(path):
            f = line.rstrip("\n").split("\t")
            if f[0] == "build":
                builds.append((f[1], int(f[2]), f[3], float(f[5])))
            elif f[0] == "query" and f[4].endswith("%"):
                scene, n, engine = f[1], int(f[2]), f[3]
                sizes[scene] = n
                queries[scene][engine].append(
                    (float(f[5]), float(f[6]), float(f[9]), float(f[12]), float(f[15])))
    out = []
    for scene, engines in queries.items():
        fig, ax = plt.subplots(figsize=(7, 4.5))
        floor_drawn = False
        for engine, pts in sorted(engines.items()):
            if engine.startswith("boost"):
                continue
            pts.sort()
            x = [p[0] * 100 for p in pts]
            ax.plot(x, [max(p[2], 1e-2) for p in pts], marker="o", label=engine)
            if engine == "mktree-pagefile-zstd" and not floor_drawn:
                ax.plot(x, [max(p[3], 1e-2) for p in pts], "k--", label="I/O floor ceil(T/B), mktree zstd")
                floor_drawn = True
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("box side, % of scene diagonal")
        ax.set_ylabel("pages read per query (cold, mean)")
        ax.set_title(f"{scene}: {sizes[scene]} objects")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        name = f"pages_{scene}.png"
        fig.savefig(os.path.join(d, name), dpi=110)
        plt.close(fig)
        out.append(f"![pages read against box size, {scene}]({name})")
    tanker = [b for b in builds if b[0].startswith("tanker")]
    if tanker:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        per_engine = defaultdict(list)
        for scene, n, engine, ops in tanker:
            per_engine[engine].append((n, ops))
        for engine, pts in sorted(per_engine.items()):
            pts.sort()
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=engine)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("objects (synthetic tanker)")
        ax.set_ylabel("build throughput, objects/s")
        ax.set_title("build throughput against N")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(d, "build_throughput.png"), dpi=110)
        plt.close(fig)
        out.append("![build throughput against N](build_throughput.png)")
    print("## Plots\n")
    print("\n\n".join(out))


if __name__ == "__main__":
    main(sys.argv[1])
