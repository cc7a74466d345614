#!/usr/bin/env python3
"""Clash benchmark: mktree clash/collide against the in-RAM peers FCL and CGAL (bench/README.md, "Clash").

Usage: scripts/bench_clash.py [--smoke] [--objects N ...] [--no-real] [--no-tanker] [--clearance C]
                              [--touch-tolerance T] [--cache-percent P] [--engines LIST] [--run NAME]
  --objects N ...   tanker sizes (default: 100000); the issue's headline is 1000000
  --clearance C     clearance in metres (default 0: meeting pairs only)
  --touch-tolerance T  passed to mktree (default 0.002); the peers report meeting only, not depth
  --cache-percent P mktree clash cache as a percentage of the store's pages (default 5)
  --engines LIST    comma-separated subset of fcl,cgal,mktree (default: all)
  --no-collide      skip the one-object-against-the-scene workload
  --run NAME        report folder bench/results/NAME (default: clash-<date>)
  --smoke           CI check: a 20k tanker and duplex.obj, report in a temporary folder; exits 1 when the
                    engines disagree on the meeting pairs
Builds clash_peers and mktree into $BENCH_BUILD (default build-bench/; $MKTREE_BIN overrides the mktree); stores go to $BENCH_TMP (default
/work/tmp-bench) and are removed. Pages: 12 KiB (--block-size 4096 --blocks-per-page 3), paged-file backend.
"""
import argparse
import datetime
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REAL = ["buildings/duplex.obj", "city/denhaag_01.obj", "buildings/steel_mini_project.obj", "ships/truman.ac"]
PEERS = ["fcl", "cgal"]


TIME = "/usr/bin/time"


def run_measured(cmd, stdout_path=None):
    """Runs cmd; returns (exit code, wall seconds, peak RSS KiB of the child, stdout text or None).

    The RSS comes from /usr/bin/time: Linux carries a forked child's pre-exec high-water mark (here this
    script's own RSS, which grows with the pair sets it holds) into ru_maxrss, so wait4 on a child of this
    process would over-report small runs; /usr/bin/time's own children start from its few MiB."""
    rss_file = None
    if os.access(TIME, os.X_OK):
        fd, rss_file = tempfile.mkstemp(prefix="clash_rss.")
        os.close(fd)
        cmd = [TIME, "-f", "%M", "-o", rss_file] + cmd
    out = open(stdout_path, "w") if stdout_path else subprocess.PIPE
    t0 = time.monotonic()
    p = subprocess.run(cmd, stdout=out, stderr=subprocess.PIPE, text=True)
    wall = time.monotonic() - t0
    if stdout_path:
        out.close()
    rss = 0
    if rss_file:
        with open(rss_file) as f:
            lines = [l for l in f.read().split() if l.isdigit()]
        rss = int(lines[-1]) if lines else 0
        os.unlink(rss_file)
    if p.returncode != 0:
        sys.stderr.write(f"bench_clash: {' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    return p.returncode, wall, rss, None if stdout_path else p.stdout


def last_line(path):
    with open(path, "rb") as f:
        f.seek(0, os.SEEK_END)
        f.seek(max(0, f.tell() - 65536))
        return f.read().decode().strip().splitlines()[-1]


def read_pairs(path, collide=False):
    """{key: summary} of pair lines; key (a, b), or the scene object's id for collide output. The summary
    keeps only "meeting" and "class" (interned): a 1M tanker has 10M pairs per engine, and whole parsed lines
    took more than the machine's 24 GiB."""
    pairs = {}
    kept = {}
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line:
                continue
            j = json.loads(line)
            if "a" not in j and "object" not in j:
                continue  # a summary line
            if collide:
                key = j["object"] if "object" in j else (j["b"] if j.get("a", -1) < 0 else j["a"])
            else:
                key = (j["a"], j["b"])
            small = (j.get("meeting"), j.get("class"))
            summary = kept.get(small)
            if summary is None:
                summary = kept[small] = {k: v for k, v in zip(("meeting", "class"), small) if v is not None}
            pairs[key] = summary
    return pairs


def meets(j):
    """Meets in the stored geometry (what every engine tests). mktree's "resolution_gap" touches are apart
    there by at most the float32 rounding of their vertices (docs/clash.md): counted apart, see compare()."""
    if "meeting" in j:
        return j["meeting"] not in ("apart", "resolution_gap")
    return j.get("class") in ("hard", "touch")


def has_clash_cli(mktree):
    if not mktree or not os.access(mktree, os.X_OK):
        return False
    # An unknown subcommand's --help prints the main help (exit 0): look for the subcommand's own usage line.
    r = subprocess.run([mktree, "clash", "--help"], capture_output=True, text=True)
    return r.returncode == 0 and any(l.startswith("Usage:") and " clash " in l for l in r.stdout.splitlines())


def write_object(path, bounds):
    """A closed box 'pipe route' through the scene: 60 % of the scene's x extent, 1 % of its diagonal across."""
    lo, hi = bounds[:3], bounds[3:]
    c = [(lo[k] + hi[k]) / 2 for k in range(3)]
    diag = math.sqrt(sum((hi[k] - lo[k]) ** 2 for k in range(3)))
    h = [0.3 * (hi[0] - lo[0]), 0.005 * diag, 0.005 * diag]
    v = [(c[0] + sx * h[0], c[1] + sy * h[1], c[2] + sz * h[2]) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    # Corners indexed x*4 + y*2 + z; outward-facing triangles of the six faces.
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
             (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    with open(path, "w") as f:
        f.write("o route\n")
        for p in v:
            f.write("v %.17g %.17g %.17g\n" % p)
        for t in faces:
            f.write("f %d %d %d\n" % tuple(i + 1 for i in t))


def compare(results, ref_name, collide, report):
    """Diffs every engine's meeting pairs against the reference's; returns the number of unexplained differences."""
    ref = results[ref_name]["pairs"]
    ref_meet = {k for k, j in ref.items() if meets(j)}
    bad = 0
    for name, r in results.items():
        if name == ref_name or r.get("pairs") is None:
            continue
        got = {k for k, j in r["pairs"].items() if meets(j)}
        missing, extra = sorted(ref_meet - got), sorted(got - ref_meet)
        explained = []
        if name == "fcl":
            # FCL tests triangles only: a solid wholly inside another is no collision to it.
            explained = [k for k in missing if ref[k].get("meeting") in ("a_inside_b", "b_inside_a")]
            missing = [k for k in missing if k not in set(explained)]
        line = f"- {name} vs {ref_name}: {len(got)} meeting, {len(missing)} missing, {len(extra)} extra"
        if explained:
            line += f", {len(explained)} containment pairs not found (FCL has no containment test; expected)"
        gaps = sum(1 for j in r["pairs"].values() if j.get("meeting") == "resolution_gap")
        if gaps:
            line += f"; also {gaps} touches apart by at most the stored resolution (exact input touches)"
        report.append(line)
        for k in missing[:10]:
            report.append(f"  - missing {k}: {ref_name} says {json.dumps(ref[k])}")
        for k in extra[:10]:
            report.append(f"  - extra {k}: {name} says {json.dumps(r['pairs'][k])}")
        bad += len(missing) + len(extra)
    return bad


def main():
    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("--smoke", action="store_true")
    ap.add_argument("--objects", type=int, nargs="+")
    ap.add_argument("--no-real", action="store_true")
    ap.add_argument("--no-tanker", action="store_true")
    ap.add_argument("--no-collide", action="store_true")
    ap.add_argument("--clearance", type=float, default=0.0)
    ap.add_argument("--touch-tolerance", type=float, default=0.002)
    ap.add_argument("--cache-percent", type=float, default=5.0)
    ap.add_argument("--engines", default="fcl,cgal,mktree")
    ap.add_argument("--run")
    ap.add_argument("-h", "--help", action="store_true")
    args = ap.parse_args()
    if args.help:
        print(__doc__)
        return 0
    engines = args.engines.split(",")
    for e in engines:
        if e not in PEERS + ["mktree"]:
            sys.exit(f"bench_clash: unknown engine {e}")
    data = os.environ.get("MKTREE_DATA", os.path.join(os.path.dirname(REPO), "shared", "data"))
    objects = args.objects or ([20000] if args.smoke else [100000])
    real = [] if args.no_real else (["buildings/duplex.obj"] if args.smoke else REAL)

    build = os.environ.get("BENCH_BUILD", os.path.join(REPO, "build-bench"))
    subprocess.run([os.path.join(REPO, "scripts/setup.sh"), "--no-build"], check=True)
    subprocess.run(["cmake", "-S", REPO, "-B", build, "-DCMAKE_BUILD_TYPE=Release"], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", build, "-j", "2", "--target", "clash_peers", "mktree"], check=True,
                   stdout=subprocess.DEVNULL)
    peers_bin = os.path.join(build, "bench", "clash_peers")
    mktree_bin = os.environ.get("MKTREE_BIN", os.path.join(build, "mktree"))  # e.g. a wip/clash build
    mktree_ok = "mktree" in engines and has_clash_cli(mktree_bin)

    tmp_root = os.environ.get("BENCH_TMP", "/work/tmp-bench")
    try:
        os.makedirs(tmp_root, exist_ok=True)
    except OSError:
        tmp_root = tempfile.gettempdir()
    work = tempfile.mkdtemp(prefix="clash.", dir=tmp_root)
    out_dir = os.path.join(work, "report") if args.smoke else os.path.join(
        REPO, "bench", "results", args.run or "clash-" + datetime.date.today().isoformat())
    os.makedirs(out_dir, exist_ok=True)

    versions = subprocess.run([peers_bin, "--versions"], capture_output=True, text=True).stdout.strip()
    commit = subprocess.run(["git", "-C", REPO, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    cpu = "unknown"
    for line in open("/proc/cpuinfo"):
        if line.startswith("model name"):
            cpu = line.split(":", 1)[1].strip()
            break
    ram = int(open("/proc/meminfo").readline().split()[1]) / 1048576
    report = [
        "# Clash: mktree vs FCL and CGAL (in RAM)", "",
        f"- `scripts/bench_clash.py {' '.join(sys.argv[1:])}` on "
        f"{datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC, commit {commit}",
        f"- Machine: {os.cpu_count()} cores, {cpu}, {ram:.1f} GiB RAM, {platform.system()} {platform.release()}; "
        f"load {' '.join(open('/proc/loadavg').read().split()[:3])}",
        f"- Peers: {versions} (Debian libfcl-dev, libcgal-dev); one thread each; the scene loaded whole into RAM",
        f"- mktree: paged-file store, 12 KiB pages (--block-size 4096 --blocks-per-page 3), clash cache "
        f"{args.cache_percent:g} % of the store's pages, C = {args.clearance:g} m, T = {args.touch_tolerance:g} m"
        + ("" if mktree_ok else " — **not available** (this build's mktree has no `clash` subcommand)"),
        "- Scenes: the synthetic tanker seed 1 (`tanker:N:1`, the same generator for every engine), and the real "
        "scenes of shared/data. The peers test the float32 vertices a store decodes (bench/clash_peers.cc).",
        "- Time: wall seconds of the whole process (load + index + clash) and the clash alone as the engine "
        "reports it: for mktree from the routing to the last pair handed to its visitor (which writes the pair "
        "lines), for the peers finding the pairs plus sorting and writing their lines (bench/clash_peers.cc); the "
        "collide workload also runs mktree on one thread (mktree-1t), as the peers run; RSS: the process's peak (/usr/bin/time %M, i.e. wait4's ru_maxrss of a child forked by a small process).", ""]

    scenes = []
    if not args.no_tanker:
        scenes += [(f"tanker:{n}:1", f"tanker_{n}") for n in objects]
    for f in real:
        p = os.path.join(data, f)
        if os.path.exists(p):
            scenes.append((p, os.path.splitext(os.path.basename(f))[0]))
        else:
            report.append(f"- {p} not found: skipped")
    status = 0
    table = ["| scene | workload | engine | pairs | meeting | wall s | clash s | peak RSS MiB | pages read / store | vs FCL time, RSS | vs CGAL time, RSS |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    notes = []
    for spec, name in scenes:
        print(f"== {name}", flush=True)
        bounds = None
        store_pages = None
        # Self-clash first (the peers' summary gives the scene bounds for the collide object).
        for wl in ["self", "collide"]:
            if wl == "collide" and (args.no_collide or bounds is None):
                continue
            obj_path = None
            if wl == "collide":
                obj_path = os.path.join(work, f"{name}_route.obj")
                write_object(obj_path, bounds)
            results = {}
            for e in [e for e in engines if e in PEERS]:
                pairs_path = os.path.join(work, f"{name}_{wl}_{e}.jsonl")
                cmd = [peers_bin, "--engine", e, "--scene", spec, "--clearance", repr(args.clearance),
                       "--pairs", pairs_path]
                if obj_path:
                    cmd += ["--object", obj_path]
                rc, wall, rss, text = run_measured(cmd)
                if rc != 0:
                    status = 1
                    continue
                summary = json.loads(text.strip().splitlines()[-1])
                bounds = bounds or summary["bounds"]
                results[e] = {"wall": wall, "rss": rss, "clash": summary["clash_seconds"],
                              "pairs": read_pairs(pairs_path, wl == "collide"), "summary": summary}
                print(f"   {wl} {e}: {summary['pairs']} pairs, {wall:.2f} s, {rss / 1024:.0f} MiB", flush=True)
            if mktree_ok:
                store = os.path.join(work, f"{name}.mkt")
                if not os.path.exists(store):
                    b = [mktree_bin, "build", spec, "-o", store, "--backend", "pagefile", "--block-size", "4096",
                         "--blocks-per-page", "3", "-q"]
                    rc, bwall, brss, _ = run_measured(b)
                    if rc != 0:
                        status = 1
                        continue
                    info = json.loads(subprocess.run([mktree_bin, "info", store, "--json"], capture_output=True,
                                                     text=True, check=True).stdout)
                    store_pages = info["pages"]
                    notes.append(f"- {name}: mktree build {bwall:.1f} s, {brss / 1024:.0f} MiB peak, "
                                 f"{store_pages} pages")
                cache = max(1, math.ceil(store_pages * args.cache_percent / 100))
                common = ["--cache-pages", str(cache), "--clearance", repr(args.clearance), "--touch-tolerance",
                          repr(args.touch_tolerance)]
                cmd = [mktree_bin, "clash", store] if wl == "self" else [mktree_bin, "collide", store, "--object", obj_path]
                # Collide also on one thread, as the peers run (the default uses every core).
                variants = [("mktree", [])] + ([("mktree-1t", ["--threads", "1"])] if wl == "collide" else [])
                for engine, extra in variants:
                    pairs_path = os.path.join(work, f"{name}_{wl}_{engine}.jsonl")
                    # One run, pairs and the summary line to a file (as the peers write theirs): a 1M tanker's
                    # 10M pairs are 3.7 GB of text, not to be held in this process.
                    rc, wall, rss, _ = run_measured(cmd + common + extra + ["--summary"], pairs_path)
                    if rc != 0:
                        status = 1
                        continue
                    summary = json.loads(last_line(pairs_path))
                    results[engine] = {"wall": wall, "rss": rss, "clash": summary.get("seconds", wall),
                                       "pairs": read_pairs(pairs_path, wl == "collide"), "summary": summary,
                                       "pages": f"{summary.get('pages_read')} / {summary.get('store_pages')}",
                                       }
            elif "mktree" in engines:
                results["mktree"] = None
            # Table rows.
            for e, r in results.items():
                if r is None:
                    table.append(f"| {name} | {wl} | mktree | not available | | | | | | | |")
                    continue
                nmeet = sum(1 for j in r["pairs"].values() if meets(j))
                ratios = []
                for p in PEERS:
                    q = results.get(p)
                    ratios.append("" if (q is None or p == e) else
                                  f"{r['wall'] / q['wall']:.2f}x, {r['rss'] / q['rss']:.2f}x")
                # Milliseconds are not enough below 0.1 s (a 100k collide takes about 7 ms in each engine).
                clash_s = f"{r['clash']:.4f}" if r["clash"] < 0.1 else f"{r['clash']:.3f}"
                table.append(f"| {name} | {wl} | {e} | {len(r['pairs'])} | {nmeet} | {r['wall']:.2f} | "
                             f"{clash_s} | {r['rss'] / 1024:.0f} | {r.get('pages', '')} | {ratios[0]} | {ratios[1]} |")
            live = {e: r for e, r in results.items() if r is not None}
            ref = "cgal" if "cgal" in live else ("mktree" if "mktree" in live else None)
            if ref and len(live) > 1:
                notes.append(f"{name} {wl}: meeting pairs against {ref}")
                bad = compare(live, ref, wl == "collide", notes)
                if bad:
                    status = 1
    report += table + ["", "Agreement on the meeting pairs:", ""] + notes + [""]
    text = "\n".join(report) + "\n"
    print(text)
    if not args.smoke:
        with open(os.path.join(out_dir, "REPORT.md"), "w") as f:
            f.write(text)
        print(f"bench_clash: report in {out_dir}/REPORT.md")
    shutil.rmtree(work, ignore_errors=True)
    print("bench_clash: engines agree on the meeting pairs" if status == 0 else
          "bench_clash: DISAGREEMENT or failure (see above)")
    return status


if __name__ == "__main__":
    sys.exit(main())
