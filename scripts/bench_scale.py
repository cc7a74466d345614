#!/usr/bin/env python3
"""Scale benchmark (issue 21 item 5): mktree on tankers of growing size, one size at a time.

Usage: scripts/bench_scale.py [--objects N ...] [--queries Q] [--backend pagefile|hdf5] [--run NAME] [--keep]
  --objects N ...  tanker sizes (default: 1000000 10000000 30000000); 100000000 needs ~33 GB of disk
  --queries Q      cold queries of each kind (default 500: point, boxes of 0.5, 2 and 8 m)
  --run NAME       report folder bench/results/NAME (default: scale-<date>)
  --smoke          20k and 100k objects, 20 queries, report in a temporary folder (checks the script runs)
Per size: `mktree build tanker:N:1` (wall time, objects/s, peak RSS, store bytes), the open (`mktree info`:
wall time and peak RSS), and `mktree query --queries --cold --direct-io --summary` (pages read per query of
each kind against the floor ceil(hits / B), open included in the query run's RSS). Builds $BENCH_BUILD
(default build-bench/) unless $MKTREE_BIN names the tool; stores go to $BENCH_TMP (default /work/tmp-bench)
and are removed unless --keep. Writes REPORT.md, results.json and scale.png (build time and peak RSS against
N, log-log) to the report folder. Not a CI job: the 30M build takes about 5 minutes and 10 GB of disk.
"""
import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TIME = "/usr/bin/time"


def run_measured(cmd):
    """(wall seconds, peak RSS KiB, stdout) of cmd; exits on failure. RSS from /usr/bin/time (see bench_clash.py
    for why not wait4)."""
    fd, rss_file = tempfile.mkstemp(prefix="scale_rss.")
    os.close(fd)
    t0 = time.monotonic()
    p = subprocess.run([TIME, "-f", "%M", "-o", rss_file] + cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                       text=True)
    wall = time.monotonic() - t0
    with open(rss_file) as f:
        digits = [w for w in f.read().split() if w.isdigit()]
    os.unlink(rss_file)
    if p.returncode != 0:
        sys.exit(f"bench_scale: {' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    return wall, int(digits[-1]) if digits else 0, p.stdout + p.stderr


def best_open(mk, store, runs=3):
    """(best wall seconds, its CPU seconds, largest peak RSS KiB) of `mktree info` over `runs` warm opens: the
    machine is shared, so the best wall time and the CPU time (user + system) say more than one run."""
    best = None
    rss = 0
    for _ in range(runs):
        fd, out_file = tempfile.mkstemp(prefix="scale_open.")
        os.close(fd)
        t0 = time.monotonic()
        p = subprocess.run([TIME, "-f", "%M %U %S", "-o", out_file, mk, "info", store], stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True)
        wall = time.monotonic() - t0
        with open(out_file) as f:
            fields = f.read().split()[-3:]
        os.unlink(out_file)
        if p.returncode != 0:
            sys.exit(f"bench_scale: mktree info {store} failed ({p.returncode}):\n{p.stderr}")
        rss = max(rss, int(fields[0]))
        cpu = float(fields[1]) + float(fields[2])
        if best is None or wall < best[0]:
            best = (wall, cpu)
    return best[0], best[1], rss


def tool():
    if os.environ.get("MKTREE_BIN"):
        return os.environ["MKTREE_BIN"]
    build = os.environ.get("BENCH_BUILD", os.path.join(REPO, "build-bench"))
    subprocess.run(["cmake", "-S", REPO, "-B", build, "-DCMAKE_BUILD_TYPE=Release"], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", build, "-j2", "--target", "mktree"], check=True, stdout=subprocess.DEVNULL)
    return os.path.join(build, "mktree")


def parse_summary(text):
    """{kind: {mean_hits, pages, p99, floor}} from `mktree query --summary`'s table."""
    rows = {}
    for line in text.splitlines():
        w = line.split()
        if len(w) >= 8 and w[0] in ("point", "box"):
            kind = "point" if w[0] == "point" else f"box {w[1]}"
            v = w[1:] if w[0] == "point" else w[2:]
            rows[kind] = {"queries": int(v[0]), "mean_hits": float(v[1]), "pages": float(v[2]), "p99": float(v[4]),
                          "floor": float(v[5])}
    return rows


def measure(mk, n, queries, backend, tmp, keep):
    store = os.path.join(tmp, f"tanker_{n}.mkt")
    qfile = os.path.join(tmp, f"queries_{n}.txt")
    r = {"objects": n}
    print(f"bench_scale: {n} objects: build", flush=True)
    r["build_seconds"], r["build_rss_kib"], _ = run_measured(
        [mk, "build", f"tanker:{n}:1", "-o", store, "--backend", backend])
    r["objects_per_second"] = n / r["build_seconds"]
    r["store_bytes"] = os.path.getsize(store)
    # The open alone: the first from a cold OS cache is the disk's, then the best of three warm ones the engine's.
    subprocess.run(["sh", "-c", "sync; echo 1 > /proc/sys/vm/drop_caches"], stderr=subprocess.DEVNULL)
    r["open_cold_seconds"], r["open_cold_rss_kib"], _ = run_measured([mk, "info", store])
    r["open_seconds"], r["open_cpu_seconds"], r["open_rss_kib"] = best_open(mk, store)
    subprocess.run([mk, "generate", "queries", store, "--count", str(queries), "--seed", "7", "-o", qfile],
                   check=True, stdout=subprocess.DEVNULL)
    print(f"bench_scale: {n} objects: queries", flush=True)
    r["query_seconds"], r["query_rss_kib"], out = run_measured(
        [mk, "query", store, "--queries", qfile, "--cold", "--direct-io", "--summary"])
    r["queries"] = parse_summary(out)
    if not keep:
        os.unlink(store)
    os.unlink(qfile)
    return r


def plot(results, path):
    """Draws scale.png; when this Python has no matplotlib, installs Debian's python3-matplotlib if missing and
    draws with /usr/bin/python3 (the python3 on PATH may be another installation)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        if sys.executable == "/usr/bin/python3" or not os.access("/usr/bin/python3", os.X_OK):
            print("bench_scale: no matplotlib (Debian: python3-matplotlib): no plot")
            return False
        check = ["/usr/bin/python3", "-c", "import matplotlib"]
        if subprocess.run(check, stderr=subprocess.DEVNULL).returncode != 0:
            sudo = [] if os.geteuid() == 0 else ["sudo", "-n"]
            subprocess.run(sudo + ["apt-get", "install", "-y", "-qq", "--no-install-recommends", "python3-matplotlib"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        data = os.path.join(os.path.dirname(path), "results.json")
        return subprocess.run(["/usr/bin/python3", os.path.abspath(__file__), "--plot-only", data, path]).returncode == 0
    n = [r["objects"] for r in results]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].loglog(n, [r["build_seconds"] for r in results], "o-", label="build (wall s)")
    ax[0].loglog(n, [n_ / 250000 for n_ in n], "k--", label="250k objects/s")
    ax[0].set_xlabel("objects")
    ax[0].set_ylabel("seconds")
    ax[0].legend()
    ax[1].loglog(n, [r["build_rss_kib"] / 1024 for r in results], "o-", label="build peak RSS")
    ax[1].loglog(n, [r["open_rss_kib"] / 1024 for r in results], "s-", label="open peak RSS")
    ax[1].loglog(n, [r["query_rss_kib"] / 1024 for r in results], "^-", label="cold queries peak RSS")
    ax[1].loglog(n, [n_ * 60 / 2**20 for n_ in n], "k--", label="60 B/object")
    ax[1].set_xlabel("objects")
    ax[1].set_ylabel("MiB")
    ax[1].legend()
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
    fig.suptitle("mktree on the synthetic tanker: how cost grows with N")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return True


def report(results, args, folder, plotted):
    mib = lambda kib: f"{kib / 1024:,.0f} MiB"
    sizes = ", ".join(f"{r['objects']:,}" for r in results)
    lines = [f"# Scale: mktree on tankers of {sizes} objects", "",
             f"{datetime.datetime.now().isoformat(timespec='seconds')}, {platform.node()}, {os.cpu_count()} cores; "
             f"`mktree build tanker:N:1 --backend {args.backend}` (12 KiB pages, zstd 3), `mktree info` (open), "
             f"`mktree query --cold --direct-io --summary` over {args.queries} queries of each kind "
             "(`generate queries --seed 7`). Wall seconds of the whole process; peak RSS from /usr/bin/time.", "",
             "| objects | build | objects/s | build peak RSS | B/object | store | open (cold OS cache) | open (best of 3, "
             "CPU) | open RSS |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in results:
        lines.append(f"| {r['objects']:,} | {r['build_seconds']:.1f} s | {r['objects_per_second']:,.0f} | "
                     f"{mib(r['build_rss_kib'])} | {r['build_rss_kib'] * 1024 / r['objects']:.0f} | "
                     f"{r['store_bytes'] / 2**30:.2f} GiB | {r['open_cold_seconds']:.2f} s | {r['open_seconds']:.2f} s "
                     f"({r.get('open_cpu_seconds', float('nan')):.2f} s) | "
                     f"{mib(r['open_rss_kib'])} |")
    lines += ["", "Cold pages read per query (mean, p99) against the floor ceil(hits / B):", "",
              "| objects | " + " | ".join(["point", "box 0.5", "box 2", "box 8"]) + " | query run peak RSS |",
              "|---:|---|---|---|---|---:|"]
    for r in results:
        cells = []
        for k in ["point", "box 0.5", "box 2", "box 8"]:
            q = r["queries"].get(k)
            cells.append(f"{q['pages']:.2f} (p99 {q['p99']:.0f}), floor {q['floor']:.2f}, {q['mean_hits']:.1f} hits"
                         if q else "-")
        lines.append(f"| {r['objects']:,} | " + " | ".join(cells) + f" | {mib(r['query_rss_kib'])} |")
    if plotted:
        lines += ["", "![build time and RSS against N](scale.png)"]
    with open(os.path.join(folder, "REPORT.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    p = argparse.ArgumentParser(usage=__doc__)
    p.add_argument("--objects", type=int, nargs="+", default=[1000000, 10000000, 30000000])
    p.add_argument("--queries", type=int, default=500)
    p.add_argument("--backend", default="pagefile", choices=["pagefile", "hdf5"])
    p.add_argument("--run", default="scale-" + datetime.date.today().isoformat())
    p.add_argument("--keep", action="store_true")
    p.add_argument("--smoke", action="store_true")
    p.add_argument("--plot-only", nargs=2, metavar=("RESULTS_JSON", "PNG"), help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.plot_only:
        with open(args.plot_only[0]) as f:
            sys.exit(0 if plot(json.load(f), args.plot_only[1]) else 1)
    if args.smoke:
        args.objects, args.queries = [20000, 100000], 20
    folder = tempfile.mkdtemp(prefix="scale_smoke.") if args.smoke else os.path.join(REPO, "bench", "results",
                                                                                       args.run)
    os.makedirs(folder, exist_ok=True)
    tmp = os.environ.get("BENCH_TMP", "/work/tmp-bench")
    os.makedirs(tmp, exist_ok=True)
    mk = tool()
    results = []
    for n in args.objects:
        results.append(measure(mk, n, args.queries, args.backend, tmp, args.keep))
        with open(os.path.join(folder, "results.json"), "w") as f:
            json.dump(results, f, indent=1)
    report(results, args, folder, plot(results, os.path.join(folder, "scale.png")))
    print(f"bench_scale: report in {folder}")


if __name__ == "__main__":
    main()
