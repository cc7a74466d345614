#!/usr/bin/python3
"""Hostile-input campaign for one `mktree` binary (issue 18's closing table).

Runs the binary through seeded, deterministic hostile cases in seven categories and classifies every case:
crash (killed by a signal), hang (per-case timeout, or a runaway writer past the file-size limit), silent
wrong answer (exit 0 with an answer that differs from the expected one), unclean error (non-zero exit
without exactly one `error: ...` line naming the file, or files left behind, or a previous store damaged),
clean error, ok. See bench/hostile/README.md.

    scripts/hostile.py --mktree build/mktree --out /tmp/hostile [--only CATEGORY] [--seed N] [--case ID]

Writes OUT/table.md (the table), OUT/details.md (every case that is not a clean error or ok, with its
reproducer), OUT/cases.json (every case) and OUT/cases/<ID>/ (the inputs of each reported case).
Debian's /usr/bin/python3; python3-h5py for the HDF5 crafted stores (installed with apt when missing).
"""
import argparse
import ctypes
import hashlib
import json
import math
import os
import random
import re
import resource
import shlex
import shutil
import signal
import stat
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

CATEGORIES = ["corrupt", "crafted", "scenes", "args", "disk", "kills", "concurrency", "shards", "changes",
              "changes-sharded"]
ROWS = [
    ("corrupt", "corrupt stores"),
    ("crafted", "crafted stores"),
    ("crafted-semantic", "crafted stores: semantic tampering"),
    ("scenes", "malformed scenes"),
    ("args", "arguments"),
    ("disk", "full disk"),
    ("kills", "kills"),
    ("concurrency", "concurrency"),
    ("shards", "sharded stores"),
    ("changes-rev", "changes: revision files"),
    ("changes-delta", "changes: delta and base stores"),
    ("changes-ids", "changes: id files"),
    ("changes-store", "changes: store file and folder replaced"),
    ("changes-kills", "changes: kills of update and compact"),
    ("changes-concurrency", "changes: readers during updates"),
    ("changes-args", "changes: bad arguments"),
    ("changes-sharded", "changes: a sharded store's shard files"),
    ("changes-sharded-kills", "changes: kills on a sharded store"),
]
OUTCOMES = ["ok", "clean", "unclean", "wrong", "hang", "crash"]  # by severity
COLUMN_TITLES = [("crash", "crashes"), ("hang", "hangs"), ("wrong", "silent wrong"),
                 ("unclean", "unclean errors"), ("clean", "clean errors"), ("ok", "ok")]

MEM_LIMIT = 3 << 30    # address space per run: a runaway allocation aborts instead of eating the machine
FSIZE_LIMIT = 1 << 30  # largest file a run may write: no legitimate case writes more than ~20 MB
NO_INDEX = 0xFFFFFFFF
PROGRESS_RE = re.compile(r"^[\w .-]+: \d+(/\d+ \(\d+%\))? [\d.]+s$")

# docs/cli.md, `mktree info --json`.
INFO_KEYS = {"file", "file_bytes", "backend", "codec", "objects", "nodes", "internal_nodes", "leaves", "pages",
             "height", "block_size", "blocks_per_page", "page_bytes", "balance_r", "split_nodes", "split_cells",
             "split_both_cells", "page_fill", "ram_bytes", "leaf_filter_bytes", "origin", "bounds", "record_pages", "tree"}
TREE_KEYS = {"objects", "height", "internal_nodes", "leaves", "pages", "multi_page_leaves", "min_objects_per_leaf",
             "mean_objects_per_leaf", "max_objects_per_leaf", "mem_page", "mean_page_fill", "min_page_fill",
             "split_tree_nodes", "max_split_tree_nodes", "split_tree_cells", "both_cells", "overlap_objects",
             "index_bytes_per_object", "tree_bytes_per_object", "levels"}
LEVEL_KEYS = {"depth", "nodes", "internal_nodes", "overlap_nodes", "overlap_objects", "mean_overlap_objects",
              "mean_slab_rel_width", "split_tree_nodes", "split_tree_cells", "both_cells", "both_cell_share",
              "both_volume_share"}

_xxh = ctypes.CDLL("libxxhash.so.0")
_xxh.XXH3_64bits.restype = ctypes.c_uint64
_xxh.XXH3_64bits.argtypes = [ctypes.c_char_p, ctypes.c_size_t]
_xxh.XXH3_64bits_withSeed.restype = ctypes.c_uint64
_xxh.XXH3_64bits_withSeed.argtypes = [ctypes.c_char_p, ctypes.c_size_t, ctypes.c_uint64]


def xxh3(b, seed=None):
    b = bytes(b)
    return _xxh.XXH3_64bits(b, len(b)) if seed is None else _xxh.XXH3_64bits_withSeed(b, len(b), seed)


def sha(path):
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------------------
# Running the tool


class Proc:
    def __init__(self, argv, cwd):
        self.argv, self.cwd = list(argv), str(cwd)
        self.rc = None
        self.sig = None
        self.timed_out = False
        self.out = self.err = ""
        self.secs = 0.0

    @property
    def exited(self):
        return not self.timed_out and self.sig is None

    def status(self):
        if self.timed_out:
            return "timed out after %.0f s (killed)" % self.secs
        if self.sig is not None:
            return "killed by %s" % signal.Signals(self.sig).name
        return "exit %d" % self.rc


def _limits(nice=True):
    def f():
        resource.setrlimit(resource.RLIMIT_AS, (MEM_LIMIT, MEM_LIMIT))
        resource.setrlimit(resource.RLIMIT_FSIZE, (FSIZE_LIMIT, FSIZE_LIMIT))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        if nice:
            os.nice(5)
    return f


def spawn(argv, cwd, stdin=subprocess.DEVNULL):
    p = Proc(argv, cwd)
    p.popen = subprocess.Popen(argv, cwd=str(cwd), stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               start_new_session=True, preexec_fn=_limits())
    p.t0 = time.monotonic()
    return p


def finish(p, timeout):
    try:
        out, err = p.popen.communicate(timeout=max(0.1, timeout - (time.monotonic() - p.t0)))
    except subprocess.TimeoutExpired:
        p.timed_out = True
        try:
            os.killpg(p.popen.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = p.popen.communicate()
    p.secs = time.monotonic() - p.t0
    p.t1 = time.monotonic()
    rc = p.popen.returncode
    if not p.timed_out:
        if rc < 0:
            p.sig = -rc
        else:
            p.rc = rc
    p.out = out.decode("utf-8", "replace")
    p.err = err.decode("utf-8", "replace")
    return p


def wait_all(procs, timeout):
    """Waits for every process, noting when each one ended (t1), then collects them."""
    end = time.monotonic() + timeout
    ended = {}
    while len(ended) < len(procs) and time.monotonic() < end:
        for p in procs:
            if id(p) not in ended and p.popen.poll() is not None:
                ended[id(p)] = time.monotonic()
        time.sleep(0.005)
    for p in procs:
        finish(p, max(0.1, end - time.monotonic()))
        p.t1 = ended.get(id(p), p.t1)


def run(argv, cwd, timeout):
    return finish(spawn(argv, cwd), timeout)


def error_line_problem(stderr, names):
    """None when stderr is one `error: ` line (after warnings and progress lines) naming one of `names`."""
    lines = [l for l in stderr.splitlines() if l.strip()]
    rest = [l for l in lines if not l.startswith("warning: ") and not PROGRESS_RE.match(l)]
    if not rest:
        return "nothing on stderr"
    if len(rest) != 1:
        return "stderr has %d lines besides warnings and progress" % len(rest)
    if not rest[0].startswith("error: "):
        return "stderr does not end with an `error: ` line"
    if lines[-1] != rest[0]:
        return "the error line is not the last line"
    if names and not any(n in rest[0] for n in names):
        return "the error line names none of " + ", ".join(repr(n) for n in names)
    return None


def warned(stderr):
    return any(l.startswith("warning: ") for l in stderr.splitlines())


def snapshot(d):
    """name -> sha1 (regular files) or a type tag, for the files directly in d and one level below."""
    snap = {}
    d = Path(d)
    for root, dirs, files in os.walk(d):
        rel = Path(root).relative_to(d)
        if len(rel.parts) > 1:
            dirs[:] = []
            continue
        for name in dirs + files:
            p = Path(root) / name
            key = str(rel / name)
            try:
                st = os.lstat(p)
            except FileNotFoundError:
                continue
            if stat.S_ISREG(st.st_mode):
                snap[key] = sha(p) if st.st_size < (64 << 20) else "size:%d" % st.st_size
            elif stat.S_ISDIR(st.st_mode):
                snap[key] = "dir"
            elif stat.S_ISLNK(st.st_mode):
                snap[key] = "link:" + os.readlink(p)
            else:
                snap[key] = "special"
    return snap


def parse_answers(stdout):
    """[(query, hits)] from `mktree query` JSON lines, or raise ValueError."""
    out = []
    for line in stdout.splitlines():
        if not line.strip():
            continue
        j = json.loads(line)
        out.append((j["query"], j["kind"], list(j["hits"])))
    return out


def diff_answers(got, want):
    """None when equal, else a short description of the first difference."""
    if len(got) != len(want):
        return "%d answers, expected %d" % (len(got), len(want))
    bad = [i for i in range(len(want)) if got[i] != want[i]]
    if not bad:
        return None
    i = bad[0]
    g, w = got[i][2], want[i][2]
    extra = sorted(set(g) - set(w))[:5]
    missing = sorted(set(w) - set(g))[:5]
    dup = sorted({x for x in g if g.count(x) > 1})[:5]
    desc = "%d of %d queries differ; query %d: %d hits, expected %d" % (len(bad), len(want), got[i][0], len(g), len(w))
    if extra:
        desc += "; extra ids %s" % extra
    if missing:
        desc += "; missing ids %s" % missing
    if dup:
        desc += "; duplicated ids %s" % dup
    return desc


def check_info_json(stdout, extra_allowed=()):
    """None when stdout is one valid JSON object with only the documented keys."""
    try:
        j = json.loads(stdout)
    except ValueError as e:
        return "info --json printed invalid JSON (%s)" % str(e)[:80]
    except RecursionError:
        return "info --json printed JSON nested too deep to read"
    if not isinstance(j, dict):
        return "info --json did not print an object"
    bad = set(j) - INFO_KEYS - set(extra_allowed)
    if bad:
        return "info --json has undocumented keys %s" % sorted(bad)[:5]
    t = j.get("tree")
    if t is not None:
        if not isinstance(t, dict):
            return "info --json: tree is not an object or null"
        bad = set(t) - TREE_KEYS
        if bad:
            return "info --json: tree has undocumented keys %s" % sorted(bad)[:5]
        for lv in t.get("levels") or []:
            if not isinstance(lv, dict) or set(lv) - LEVEL_KEYS:
                return "info --json: tree.levels has undocumented keys"
    return None


# ---------------------------------------------------------------------------------------------------------
# Cases


class Case:
    def __init__(self, h, cat, num, title, row=None):
        self.h = h
        self.cat = cat
        self.row = row or cat
        self.id = "%s-%03d" % (cat, num)
        self.title = title
        self.dir = h.work / self.id
        if self.dir.exists():
            shutil.rmtree(self.dir)
        self.dir.mkdir(parents=True)
        self.repro = []          # shell lines, run from the case folder
        self.steps = []          # (label, Proc, verdict, reason)
        self.notes = []
        self.outcome = None
        self.saved = False

    def path(self, name):
        return self.dir / name

    def save_inputs(self):
        """Copies the inputs as they are before the first command, for the reproducer."""
        if self.saved:
            return
        self.saved = True
        self.keep = self.h.work / (self.id + ".inputs")
        if self.keep.exists():
            shutil.rmtree(self.keep)
        shutil.copytree(self.dir, self.keep, symlinks=True, ignore=_ignore_special)

    def say(self, line):
        self.repro.append(line)

    def record(self, label, p, verdict, reason):
        self.steps.append((label, p, verdict, reason))
        return verdict

    def note(self, s):
        self.notes.append(s)

    def worst(self):
        if not self.steps:
            return "ok"
        return max((s[2] for s in self.steps), key=OUTCOMES.index)

    def stopped(self):
        return any(s[2] in ("hang", "crash") for s in self.steps)

    def mk(self, *args, cwd=None, expect="either", names=(), check=None, protect=(), prev=(), outputs=(),
           timeout=None, warn_ok=False, label=None, repro=True, allow_new=()):
        """Runs mktree ARGS in the case folder (or cwd) and judges it.

        expect: "fail" (invalid input: exit 0 is a silent wrong answer unless warn_ok and a warning was
        printed), "succeed" (a failure is unclean), "either" (a clean error or the right answer).
        check(p) -> None or what is wrong with the answer (exit 0 only). protect: files that must stay
        byte-identical whatever happens. prev: files (a previous store) that must stay byte-identical when
        the run fails. outputs: files an exit 0 may create or replace. allow_new: names (globs) any run may
        leave.
        """
        self.save_inputs()
        cwd = Path(cwd or self.dir)
        argv = [str(self.h.mktree)] + [str(a) for a in args]
        if repro:
            self.say(("cd %s && " % shlex.quote(str(cwd)) if cwd != self.dir else "") + "$MKTREE " +
                     shlex.join(argv[1:]))
        before = snapshot(cwd)
        prot = {str(x): before.get(str(x)) for x in protect}
        prv = {str(x): before.get(str(x)) for x in prev}
        p = run(argv, cwd, timeout or self.h.timeout)
        return self.judge(label or " ".join(str(a) for a in args[:2]), p, before, cwd, expect, names, check, prot,
                          prv, outputs, warn_ok, allow_new)

    def judge(self, label, p, before, cwd, expect, names, check, prot, prv, outputs, warn_ok, allow_new):
        after = snapshot(cwd)
        outputs = {str(o) for o in outputs}
        new = [n for n in after if n not in before and not any(Path(n).match(g) for g in allow_new)]
        damaged = [n for n, h in prot.items() if after.get(n) != h]
        replaced = [n for n, h in prv.items() if after.get(n) != h]
        if p.timed_out:
            return self.record(label, p, "hang", "no exit within %.0f s" % self.h.timeout)
        if p.sig is not None:
            if p.sig == signal.SIGXFSZ:
                return self.record(label, p, "hang", "runaway output: a file past the harness's %d MiB limit" %
                                   (FSIZE_LIMIT >> 20))
            return self.record(label, p, "crash", "killed by " + signal.Signals(p.sig).name +
                               (" (rc %d in a shell)" % (128 + p.sig)))
        if p.rc == 0:
            if expect == "fail":
                if warn_ok and warned(p.err):
                    return self.record(label, p, "ok", "accepted with a warning")
                return self.record(label, p, "wrong", "accepted invalid input (exit 0, no error%s)%s" % (
                    " or warning" if warn_ok else "", "; replaced " + ", ".join(damaged + replaced)
                    if damaged + replaced else ""))
            if damaged:
                return self.record(label, p, "wrong", "exit 0 but changed " + ", ".join(damaged))
            left = [n for n in new if n not in outputs]
            if left:
                return self.record(label, p, "unclean", "exit 0 but left " + ", ".join(sorted(left)[:4]))
            if check:
                try:
                    why = check(p)
                except Exception as e:  # a harness bug: shown in the details, never silent
                    why = "harness check failed: %s: %s" % (type(e).__name__, e)
                if why:
                    return self.record(label, p, "wrong", why)
            return self.record(label, p, "ok", "")
        problems = []
        if expect == "succeed":
            problems.append("failed where it must succeed")
        if p.rc not in (1, 2):
            problems.append("exit code %d (not 1 or 2)" % p.rc)
        e = error_line_problem(p.err, names)
        if e:
            problems.append(e)
        if new:
            problems.append("left " + ", ".join(sorted(new)[:4]))
        if damaged + replaced:
            problems.append("changed " + ", ".join(damaged + replaced))
        if problems:
            return self.record(label, p, "unclean", "; ".join(problems))
        return self.record(label, p, "clean", "")


def _ignore_special(d, names):
    out = []
    for n in names:
        st = os.lstat(os.path.join(d, n))
        if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode) or stat.S_ISLNK(st.st_mode)):
            out.append(n)
    return out


# ---------------------------------------------------------------------------------------------------------
# Store models: the paged file parsed per docs/store_format.md, and the HDF5 store through h5py


NODE = struct.Struct("<6f2f4I2BH")    # 52
SPLIT = struct.Struct("<f2I2BH")      # 16
LEAF = struct.Struct("<6f2I2QII")     # 56
ENTRY = struct.Struct("<I6fBBBBIIII")  # 48


MASK64 = (1 << 64) - 1


def id_hash(i):
    """ObjectIdHash (engine/store_format/tree_codec.h): the splitmix64 finalizer of id + 1."""
    x = ((i + 1) * 0x9E3779B97F4A7C15) & MASK64
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK64
    return x ^ (x >> 31)


def reseal_page(pg):
    """Recomputes a page's XXH3 (leaf and record pages alike)."""
    struct.pack_into("<Q", pg, 24, 0)
    struct.pack_into("<Q", pg, 24, xxh3(pg[32:], xxh3(pg[:24])))


class Model:
    """A store's metadata as Python lists; pages as a bytearray per page.

    Format 5: `digests` (u64 per leaf) replace format 4's object-leaves column; each object's leaf is a u32
    in its record (record pages after the leaf pages); `obj_leaf` is read from the records, for the cases.
    """

    def node(self, i):
        v = self.nodes[i]
        return {"box": list(v[0:6]), "a": v[6], "b": v[7], "c": [v[8], v[9]], "leaf": v[10], "split": v[11],
                "axis": v[12], "depth": v[13]}

    def set_node(self, i, n):
        self.nodes[i] = tuple(n["box"]) + (n["a"], n["b"], n["c"][0], n["c"][1], n["leaf"], n["split"], n["axis"],
                                           n["depth"], 0)

    def node_tuple(self, n):
        return tuple(n["box"]) + (n["a"], n["b"], n["c"][0], n["c"][1], n["leaf"], n["split"], n["axis"],
                                  n["depth"], 0)

    def leaf(self, i):
        v = self.leaves[i]
        return {"box": list(v[0:6]), "node": v[6], "count": v[7], "payload": v[8], "first": v[9], "pages": v[10]}

    def set_leaf(self, i, l):
        self.leaves[i] = tuple(l["box"]) + (l["node"], l["count"], l["payload"], l["first"], l["pages"], 0)

    def enc_nodes(self):
        return b"".join(NODE.pack(*n) for n in self.nodes)

    def enc_splits(self):
        return b"".join(SPLIT.pack(*s) for s in self.splits)

    def enc_leaves(self):
        return b"".join(LEAF.pack(*l) for l in self.leaves)

    def enc_obj_leaves(self):
        if self.version >= 5:
            return struct.pack("<%dQ" % len(self.digests), *self.digests)
        return struct.pack("<%dI" % len(self.obj_leaf), *self.obj_leaf)

    def record_pages(self):
        n, total = len(self.rec_dir) // 4, len(self.pages_list())
        return list(range(total - n, total))

    def record_offsets(self):
        """{object id: (page, offset of its record's length field)}, groups of one page only."""
        out = {}
        for pi in self.record_pages():
            pg = self.page(pi)
            first, _, npages = struct.unpack_from("<III", pg, 8)
            if npages != 1:
                continue
            off = 40
            for k in range(struct.unpack_from("<I", pg, 32)[0]):
                out[first + k] = (pi, off)
                off += 4 + struct.unpack_from("<I", pg, off)[0]
        return out

    def record_leaf(self, oid):
        pi, off = self.record_offsets()[oid]
        return struct.unpack_from("<I", self.page(pi), off + 32)[0]

    def set_record_leaf(self, oid, leaf):
        pi, off = self.record_offsets()[oid]
        pg = bytearray(self.page(pi))
        struct.pack_into("<I", pg, off + 32, leaf)
        reseal_page(pg)
        self.set_page(pi, pg)
        return pi

    def load_record_leaves(self):
        offs = self.record_offsets()
        self.obj_leaf = [struct.unpack_from("<I", self.page(offs[i][0]), offs[i][1] + 32)[0]
                         for i in range(self.object_count)]

    def name_ends(self):
        ends, e = [], 0
        for n in self.names:
            e += len(n)
            ends.append(e)
        return ends

    def enc_name_ends(self):
        ends = self.name_ends()
        return struct.pack("<%dQ" % len(ends), *ends)

    def internal(self):
        return [i for i, n in enumerate(self.nodes) if n[12] < 3]

    def leaf_nodes(self):
        return [i for i, n in enumerate(self.nodes) if n[12] == 3]

    def parents(self):
        par = {}
        for i in self.internal():
            for c in self.nodes[i][8:10]:
                par[c] = i
        return par

    def depth_of(self, i):
        par, d = self.parents(), 0
        while i in par:
            i, d = par[i], d + 1
        return d

    def subtree(self, i):
        out, todo = set(), [i]
        while todo:
            j = todo.pop()
            if j in out or j >= len(self.nodes):
                continue
            out.add(j)
            if self.nodes[j][12] < 3:
                todo.extend(self.nodes[j][8:10])
        return out

    # Leaf pages (single-page leaves only, which is all a tanker store has).
    def leaf_entries(self, li):
        l = self.leaf(li)
        pg = self.page(l["first"])
        count, leaf_index, payload = struct.unpack_from("<IIQ", pg, 32)
        entries, off = [], 32 + 16
        for _ in range(count):
            e = list(ENTRY.unpack_from(pg, off))
            size = 48 + e[-1]
            entries.append((e, bytes(pg[off:off + size])))
            off += size
        return entries

    def reseal(self, index, leaf_index, entries, page_in_leaf=0, pages_in_leaf=1):
        """Writes page `index` holding `entries` (raw bytes each) with a valid header and checksum."""
        P = self.P
        body = b"".join(entries)
        payload = struct.pack("<IIQ", len(entries), leaf_index, 16 + len(body)) + body
        if len(payload) > P - 32:
            raise ValueError("payload does not fit the page")
        pg = bytearray(P)
        struct.pack_into("<4sHHIIII", pg, 0, b"MKPG", 1, 0, leaf_index, page_in_leaf, pages_in_leaf, len(payload))
        pg[32:32 + len(payload)] = payload
        struct.pack_into("<Q", pg, 24, xxh3(pg[32:], xxh3(pg[:24])))
        self.set_page(index, pg)
        return 16 + len(body)


class PagedModel(Model):
    backend = "pagefile"

    def __init__(self, path):
        b = open(path, "rb").read()
        if b[:8] != b"MKTREEPF":
            raise ValueError("not a paged-file store")
        self.version = struct.unpack_from("<I", b, 8)[0]
        bs, bpp = struct.unpack_from("<II", b, 16)
        self.P = P = bs * bpp
        self.page_count, self.object_count = struct.unpack_from("<QQ", b, 48)
        self.header = bytearray(b[:P])
        self.pages = [bytearray(b[P * (1 + i):P * (2 + i)]) for i in range(self.page_count)]
        # format 6: a ninth section, the codec dictionary; the header checksum and origin follow the table
        self.nsec = 9 if self.version >= 6 else 8
        self.sum_at = 80 + 24 * self.nsec
        secs = []
        for i in range(self.nsec):
            off, n, _ = struct.unpack_from("<QQQ", b, 80 + 24 * i)
            secs.append(bytes(b[off:off + n]))
        self.nodes = [NODE.unpack_from(secs[0], o) for o in range(0, len(secs[0]), NODE.size)]
        self.splits = [SPLIT.unpack_from(secs[1], o) for o in range(0, len(secs[1]), SPLIT.size)]
        self.leaves = [LEAF.unpack_from(secs[2], o) for o in range(0, len(secs[2]), LEAF.size)]
        if self.version >= 5:
            self.digests = list(struct.unpack("<%dQ" % (len(secs[3]) // 8), secs[3]))
        else:
            self.obj_leaf = list(struct.unpack("<%dI" % (len(secs[3]) // 4), secs[3]))
        if self.version >= 4:  # names live in record pages; the sections are the directory and sources
            self.rec_dir, self.sources, self.names = secs[4], secs[5], None
        else:
            ends = struct.unpack("<%dQ" % (len(secs[4]) // 8), secs[4])
            self.names, s = [], 0
            for e in ends:
                self.names.append(secs[5][s:e])
                s = e
        self.stats = secs[6]
        self.leaf_filter = bytearray(secs[7])
        self.dictionary = bytearray(secs[8]) if self.nsec > 8 else None
        self.origin = struct.unpack_from("<3d", b, self.sum_at + 8) if self.version >= 3 else (0.0, 0.0, 0.0)
        if self.version >= 5:
            self.load_record_leaves()

    def page(self, i):
        return self.pages[i]

    def set_page(self, i, pg):
        self.pages[i] = bytearray(pg)

    def save(self, path):
        P = self.P
        h = bytearray(self.header)
        struct.pack_into("<QQ", h, 48, len(self.pages), self.object_count)
        if self.names is None:
            objs = [self.rec_dir, self.sources]
        else:
            objs = [self.enc_name_ends(), b"".join(self.names)]
        secs = [self.enc_nodes(), self.enc_splits(), self.enc_leaves(), self.enc_obj_leaves()] + objs + \
            [bytes(self.stats), bytes(self.leaf_filter)]
        if self.dictionary is not None:
            secs.append(bytes(self.dictionary))
        off = P * (1 + len(self.pages))
        for i, s in enumerate(secs):
            struct.pack_into("<QQQ", h, 80 + 24 * i, off, len(s), xxh3(s))
            off += len(s)
        struct.pack_into("<Q", h, 64, off)
        struct.pack_into("<Q", h, self.sum_at, 0)
        struct.pack_into("<Q", h, self.sum_at, xxh3(h))
        with open(path, "wb") as f:
            f.write(h)
            for pg in self.pages:
                f.write(pg)
            for s in secs:
                f.write(s)


def need_h5py():
    try:
        import h5py  # noqa: F401
        return None
    except ImportError:
        pass
    r = subprocess.run(["apt-get", "install", "-y", "-q", "python3-h5py"], capture_output=True, text=True)
    try:
        import h5py  # noqa: F401
        return None
    except ImportError:
        return "python3-h5py is not installed and apt-get could not install it: " + r.stderr.strip()[-200:]


class Hdf5Model(Model):
    """Loads through h5py; save() rewrites the changed datasets in place and recomputes the checksums."""
    backend = "hdf5"

    def __init__(self, path):
        import h5py
        import numpy as np
        self.np = np
        self.path = path
        with h5py.File(path, "r") as f:
            a = f.attrs
            self.version = int(a["format_version"])
            self.P = int(a["block_size"]) * int(a["blocks_per_page"])
            self.page_count, self.object_count = int(a["page_count"]), int(a["object_count"])
            self.origin = tuple(float(x) for x in a["origin"]) if "origin" in a else (0.0, 0.0, 0.0)
            self.node_dtype = f["tree/nodes"].dtype
            self.split_dtype = f["tree/split_nodes"].dtype
            self.leaf_dtype = f["tree/leaves"].dtype
            self.nodes = [tuple(r["box_min"]) + tuple(r["box_max"]) + (r["a"], r["b"], r["child"][0], r["child"][1],
                          r["leaf"], r["split_root"], r["axis"], r["depth"], 0) for r in f["tree/nodes"][()]]
            self.nodes = [tuple(float(x) for x in n[:8]) + tuple(int(x) for x in n[8:]) for n in self.nodes]
            self.splits = [(float(r["cut"]), int(r["child"][0]), int(r["child"][1]), int(r["axis"]), int(r["label"]), 0)
                           for r in f["tree/split_nodes"][()]]
            self.leaves = [tuple(float(x) for x in tuple(r["box_min"]) + tuple(r["box_max"])) +
                           (int(r["node"]), int(r["object_count"]), int(r["payload_bytes"]), int(r["first_page"]),
                            int(r["page_count"]), 0) for r in f["tree/leaves"][()]]
            if self.version >= 5:  # format 5: leaf id digests; each object's leaf in its record
                self.digests = [int(x) for x in f["objects/leaf_digest"][()]]
                self.obj_leaf = None
                self.names = None
                self.rec_dir = f["objects/record_directory"][()].astype("<u4").tobytes()
                self.sources = f["objects/sources"][()].tobytes()
            elif self.version >= 4:  # format 4: names in record pages
                self.obj_leaf = [int(x) for x in f["objects/leaf"][()]]
                self.names = None
                self.rec_dir = f["objects/record_directory"][()].astype("<u4").tobytes()
                self.sources = f["objects/sources"][()].tobytes()
            elif isinstance(f["objects"], h5py.Group):  # format 3: the canonical object table
                self.obj_leaf = [int(x) for x in f["objects/leaf"][()]]
                ends = [int(x) for x in f["objects/name_end"][()]]
                names = f["objects/names"][()].tobytes() if f["objects/names"].shape[0] else b""
                self.names, start = [], 0
                for e in ends:
                    self.names.append(names[start:e])
                    start = e
            else:  # format 2: one compound dataset
                objs = f["objects"][()]
                self.obj_leaf = [int(x) for x in objs["leaf"]]
                self.names = [bytes(x).split(b"\0")[0] for x in objs["name"]]
            if self.version >= 5:
                self.all_pages = [bytearray(x.tobytes()) for x in f["pages"][()]]
            self.stats = bytes(f["stats_json"][()]).split(b"\0")[0]
            self.leaf_filter = bytearray(f["tree/leaf_filter"][()].tobytes())
        self.page_edits = {}
        if self.version >= 5:
            self.load_record_leaves()
        self.orig = (list(self.nodes), list(self.splits), list(self.leaves), list(self.obj_leaf), list(self.names) if self.names is not None else None,
                     self.stats, bytes(self.leaf_filter), self.object_count,
                     list(self.digests) if self.version >= 5 else None)

    def page(self, i):
        if i not in self.page_edits and self.version >= 5:
            return self.all_pages[i]
        if i not in self.page_edits:
            import h5py
            with h5py.File(self.path, "r") as f:
                self.page_edits[i] = bytearray(f["pages"][i].tobytes())
        return self.page_edits[i]

    def set_page(self, i, pg):
        self.page_edits[i] = bytearray(pg)

    def save(self, path):
        import h5py
        np = self.np
        if str(path) != str(self.path):
            shutil.copyfile(self.path, path)
        with h5py.File(path, "r+") as f:
            def rewrite(name, dtype, rows):
                arr = np.zeros(len(rows), dtype=dtype)
                for i, r in enumerate(rows):
                    arr[i] = r
                if name in f and f[name].shape == arr.shape:
                    f[name][...] = arr
                else:
                    del f[name]
                    f.create_dataset(name, data=arr)
            if self.nodes != self.orig[0]:
                rewrite("tree/nodes", self.node_dtype,
                        [(n[0:3], n[3:6], n[6], n[7], (n[8], n[9]), n[10], n[11], n[12], n[13]) for n in self.nodes])
            if self.splits != self.orig[1]:
                rewrite("tree/split_nodes", self.split_dtype, [(s[0], (s[1], s[2]), s[3], s[4]) for s in self.splits])
            if self.leaves != self.orig[2]:
                rewrite("tree/leaves", self.leaf_dtype, [(l[0:3], l[3:6], l[6], l[7], l[8], l[9], l[10])
                                                         for l in self.leaves])
            if self.version >= 5:
                if self.digests != self.orig[8]:
                    arr = np.array(self.digests, dtype="<u8")
                    if f["objects/leaf_digest"].shape == arr.shape:
                        f["objects/leaf_digest"][...] = arr
                    else:
                        del f["objects/leaf_digest"]
                        f.create_dataset("objects/leaf_digest", data=arr, chunks=(max(1, min(65536, len(arr))),),
                                         shuffle=True, compression="gzip")
            elif self.names is None and self.obj_leaf != self.orig[3]:
                del f["objects/leaf"]
                f.create_dataset("objects/leaf", data=np.array(self.obj_leaf, dtype="<u4"),
                                 chunks=(max(1, min(65536, len(self.obj_leaf))),) if self.obj_leaf else None)
            elif self.names is None:
                pass
            elif (self.obj_leaf != self.orig[3] or self.names != self.orig[4]) and isinstance(f["objects"], h5py.Group):
                def replace(name, arr):
                    del f[name]
                    f.create_dataset(name, data=arr, chunks=(max(1, min(65536, len(arr))),) if len(arr) else None)
                replace("objects/leaf", np.array(self.obj_leaf, dtype="<u4"))
                replace("objects/name_end", np.array(self.name_ends(), dtype="<u8"))
                replace("objects/names", np.frombuffer(b"".join(self.names), dtype=np.uint8))
            elif self.obj_leaf != self.orig[3] or self.names != self.orig[4]:
                d = f["objects"]
                if len(self.obj_leaf) == d.shape[0] and self.names == self.orig[4]:
                    d[...] = _with_field(d[()], "leaf", self.obj_leaf)
                else:
                    width = max([len(n) for n in self.names] + [1])
                    dt = np.dtype([("id", "<u4"), ("leaf", "<u4"), ("name", "S%d" % width)])
                    arr = np.zeros(len(self.obj_leaf), dtype=dt)
                    for i in range(len(self.obj_leaf)):
                        arr[i] = (i, self.obj_leaf[i], self.names[i])
                    del f["objects"]
                    f.create_dataset("objects", data=arr, chunks=(max(1, min(8192, len(arr))),), shuffle=True,
                                     compression="gzip")
            if self.stats != self.orig[5]:
                del f["stats_json"]
                f.create_dataset("stats_json", data=np.bytes_(self.stats if self.stats else b"\0"))
            if bytes(self.leaf_filter) != self.orig[6]:
                rewrite("tree/leaf_filter", np.uint8, list(self.leaf_filter))
            for i, pg in self.page_edits.items():
                f["pages"][i] = np.frombuffer(bytes(pg), dtype=np.uint8)
            a = f.attrs
            if self.object_count != self.orig[7]:
                a.modify("object_count", np.uint64(self.object_count))
            hdr = struct.pack("<IIdIBBHi", int(a["block_size"]), int(a["blocks_per_page"]), float(a["balance_r"]),
                              int(a["split_tree_node_budget"]), 1 if _s(a["codec"]) == "zstd" else 0,
                              int(a["shuffle"]), 0, int(a["zstd_level"]))
            hdr += struct.pack("<QQI", int(a["page_count"]), self.object_count, self.version)
            if self.version >= 3:
                hdr += struct.pack("<3d", *self.origin)
            sums = {"checksum_header": xxh3(hdr), "checksum_nodes": xxh3(self.enc_nodes()),
                    "checksum_split_nodes": xxh3(self.enc_splits()), "checksum_leaves": xxh3(self.enc_leaves()),
                    "checksum_objects": xxh3(self.enc_obj_leaves() + (self.rec_dir + self.sources if self.names is None
                                                                      else self.enc_name_ends() + b"".join(self.names))),
                    "checksum_stats_json": xxh3(self.stats), "checksum_leaf_filter": xxh3(self.leaf_filter)}
            for k, v in sums.items():
                a.modify(k, np.uint64(v))


def _s(v):
    return v.decode() if isinstance(v, bytes) else str(v)


def _with_field(arr, field, values):
    arr = arr.copy()
    arr[field] = values
    return arr


def load_model(path):
    with open(path, "rb") as f:
        head = f.read(8)
    return PagedModel(path) if head == b"MKTREEPF" else Hdf5Model(path)


# ---------------------------------------------------------------------------------------------------------
# Scenes written by the harness


def cube_faces(base):
    # 12 outward triangles of the cube whose 8 corners start at 1-based index `base` (x fastest).
    q = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    out = []
    for a, b, c, d in q:
        out.append((base + a, base + b, base + c))
        out.append((base + a, base + c, base + d))
    return out


def cube_obj(cubes, fmt="%.6f"):
    """OBJ text of axis-aligned cubes [(name, (cx, cy, cz), side)]."""
    lines = ["# cubes written by scripts/hostile.py"]
    base = 1
    for name, c, s in cubes:
        lines.append("o " + name)
        for k in range(8):
            p = [c[i] + (s / 2 if (k >> i) & 1 else -s / 2) for i in range(3)]
            lines.append("v " + " ".join(fmt % x for x in p))
        for t in cube_faces(base):
            lines.append("f %d %d %d" % t)
        base += 8
    return "\n".join(lines) + "\n"


TINY_CUBES = [("cube_%d" % i, (3.0 * (i % 3), 3.0 * ((i // 3) % 3), 1.5 * (i // 9)), 1.0 + 0.25 * (i % 4))
              for i in range(8)]

NUM_RE = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")
OBJ_IGNORED = {"vt", "vn", "vp", "l", "p", "s", "usemtl", "mtllib", "lod", "bevel", "c_interp", "d_interp", "usemap",
               "maplib", "shadow_obj", "trace_obj", "mg", "g"}
FLT_MAX = 3.4028234663852886e38


def ref_parse_obj(text):
    """A strict reference reading of an OBJ file (engine/scene/obj_reader.h semantics, `o` files only).

    Returns (verdict, objects): verdict "valid", "invalid" (unambiguously broken: non-finite or out-of-range
    coordinates, a vertex index 0 or out of range, a face of fewer than 3 vertices) or "junk" (other
    malformed lines: an unknown directive, a token that is not a number); objects: [(name, box)] for a
    valid file, in id order.
    """
    verts = []
    objs = []  # [name, box or None]
    cur = None
    verdict = "valid"

    def worse(v):
        nonlocal verdict
        if v == "invalid" or verdict == "valid":
            verdict = v

    for raw in text.split("\n"):
        line = raw.rstrip("\r")
        if "\0" in line:
            worse("junk")
            continue
        t = line.split()
        if not t or t[0].startswith("#"):
            continue
        k = t[0]
        if k == "v":
            nums = t[1:]
            if len(nums) not in (3, 4, 6, 7):
                worse("junk")
                continue
            xyz = []
            for s in nums[:3]:
                if s.lower().lstrip("+-") in ("nan", "inf", "infinity"):
                    worse("invalid")
                    xyz.append(float("nan"))
                elif not NUM_RE.match(s):
                    worse("junk")
                    xyz.append(0.0)
                else:
                    x = float(s)
                    if not math.isfinite(x) or abs(x) > FLT_MAX:
                        worse("invalid")
                    xyz.append(x)
            for s in nums[3:]:
                if not NUM_RE.match(s):
                    worse("junk")
            verts.append(xyz)
        elif k == "f":
            idx = []
            for s in t[1:]:
                parts = s.split("/")
                if len(parts) > 3 or not re.match(r"^-?\d+$", parts[0]):
                    worse("junk")
                    continue
                if any(p != "" for p in parts[1:]):
                    worse("invalid")  # the base files have no vt/vn: any such index is out of range
                i = int(parts[0])
                if i == 0 or abs(i) > len(verts):
                    worse("invalid")
                    continue
                idx.append(i - 1 if i > 0 else len(verts) + i)
            if len(t) - 1 < 3:
                worse("invalid")
                continue
            if cur is None:
                cur = ["", None]
                objs.append(cur)
            for i in idx:
                p = verts[i]
                if cur[1] is None:
                    cur[1] = [p[:], p[:]]
                else:
                    cur[1] = [[min(a, b) for a, b in zip(cur[1][0], p)], [max(a, b) for a, b in zip(cur[1][1], p)]]
        elif k == "o":
            cur = [line[1:].strip(), None]
            objs.append(cur)
        elif k in OBJ_IGNORED:
            continue
        else:
            worse("junk")
    return verdict, [(n, b) for n, b in objs if b is not None]


def write_queries(path, queries):
    with open(path, "w") as f:
        f.write("# queries written by scripts/hostile.py\n")
        for q in queries:
            if len(q) == 3:
                f.write("point %.9g %.9g %.9g\n" % tuple(q))
            else:
                f.write("box %.9g %.9g %.9g %.9g %.9g %.9g\n" % tuple(q))


# ---------------------------------------------------------------------------------------------------------
# The harness


class Harness:
    def __init__(self, args):
        self.mktree = Path(args.mktree).resolve()
        self.out = Path(args.out).resolve()
        self.seed = args.seed
        self.timeout = args.timeout
        self.only = args.only
        self.only_case = args.case
        self.work = self.out / "work"
        self.fix = self.out / "fixtures"
        self.cases = []
        self.skipped = []
        self.setup_notes = []
        self.mounts = []
        for d in (self.out, self.work, self.fix):
            d.mkdir(parents=True, exist_ok=True)
        if (self.out / "cases").exists():
            shutil.rmtree(self.out / "cases")

    def rng(self, *key):
        return random.Random("%d:%s" % (self.seed, ":".join(str(k) for k in key)))

    def log(self, s):
        print(s, flush=True)

    def tool(self, *args, cwd=None, timeout=120):
        p = run([str(self.mktree)] + [str(a) for a in args], cwd or self.fix, timeout)
        return p

    def must(self, *args, cwd=None, timeout=300):
        p = self.tool(*args, cwd=cwd, timeout=timeout)
        if p.rc != 0:
            raise SetupError("setup: mktree %s: %s: %s" % (" ".join(map(str, args)), p.status(), p.err.strip()[-300:]))
        return p

    # -- fixtures -------------------------------------------------------------------------------------
    def store(self, backend, scene="tanker:3000", extra=()):
        name = "%s_%s%s.mkt" % (scene.replace(":", "_"), backend, "".join(x.replace("-", "") for x in extra))
        path = self.fix / name
        if not path.exists():
            self.must("build", scene, "-o", path, "--backend", backend, "-q", *extra)
        return path

    def queries_for(self, store, name, n_points=30, n_uniform=10, n_box=30, n_big=10):
        """A fixed query file: points at object box centres, uniform points, boxes around object centres."""
        path = self.fix / name
        if path.exists():
            return path
        m = load_model(str(store)) if str(store).endswith("pagefile.mkt") else load_model(str(store))
        o = m.origin
        centres, boxes = [], []
        for li in range(len(m.leaves)):
            for e, _ in m.leaf_entries(li):
                b = e[1:7]
                centres.append([(b[i] + b[i + 3]) / 2 + o[i] for i in range(3)])
        root = m.node(0)["box"]
        lo = [root[i] + o[i] for i in range(3)]
        hi = [root[i + 3] + o[i] for i in range(3)]
        r = self.rng("queries", name)
        qs = [r.choice(centres) for _ in range(n_points)]
        qs += [[r.uniform(lo[i], hi[i]) for i in range(3)] for _ in range(n_uniform)]
        for side, n in ((4.0, n_box), (16.0, n_big)):
            for _ in range(n):
                c = r.choice(centres)
                boxes.append([c[i] - side / 2 for i in range(3)] + [c[i] + side / 2 for i in range(3)])
        write_queries(path, qs + boxes)
        return path

    def answers(self, store, qfile, exact=False):
        args = ["query", store, "--queries", qfile] + (["--exact"] if exact else [])
        p = self.must(*args)
        return parse_answers(p.out)

    def new_case(self, cat, num, title, row=None):
        c = Case(self, cat, num, title, row)
        return c

    def wanted(self, cat, num):
        return self.only_case is None or self.only_case == "%s-%03d" % (cat, num)

    def finish_case(self, c, require_error=False):
        c.outcome = c.worst()
        if require_error and c.outcome == "ok" and all(s[1].rc == 0 for s in c.steps):
            c.outcome = "wrong"
            c.note("every command exited 0 on a store that must be refused (at open or at the page read)")
        self.cases.append(c)
        keep = c.outcome not in ("ok", "clean")
        dest = self.out / "cases" / c.id
        if keep and c.saved:
            dest.parent.mkdir(parents=True, exist_ok=True)
            if dest.exists():
                shutil.rmtree(dest)
            shutil.move(str(c.keep), str(dest))
        elif c.saved and c.keep.exists():
            shutil.rmtree(c.keep)
        shutil.rmtree(c.dir, ignore_errors=True)
        mark = {"ok": ".", "clean": "c", "unclean": "U", "wrong": "W", "hang": "H", "crash": "X"}[c.outcome]
        print(mark, end="", flush=True)

    # -- reporting ------------------------------------------------------------------------------------
    def report(self, elapsed):
        counts = {r: {o: 0 for o in OUTCOMES} for r, _ in ROWS}
        for c in self.cases:
            counts[c.row][c.outcome] += 1
        lines = ["Binary: `%s`; seed %d; per-case timeout %.0f s; %d cases in %.0f s." %
                 (self.mktree, self.seed, self.timeout, len(self.cases), elapsed), "",
                 "| category | cases | " + " | ".join(t for _, t in COLUMN_TITLES) + " |",
                 "|---|---:|" + "---:|" * len(COLUMN_TITLES)]
        tot = {o: 0 for o in OUTCOMES}
        for r, title in ROWS:
            n = sum(counts[r].values())
            skip = [s for s in self.skipped if s[0] == r]
            if n == 0 and not skip:
                continue
            if n == 0:
                lines.append("| %s | skipped: %s |" % (title, skip[0][1]) + " |" * len(COLUMN_TITLES))
                continue
            for o in OUTCOMES:
                tot[o] += counts[r][o]
            lines.append("| %s | %d | " % (title, n) + " | ".join(str(counts[r][o]) for o, _ in COLUMN_TITLES) + " |")
        lines.append("| **total** | **%d** | " % sum(tot.values()) +
                     " | ".join("**%d**" % tot[o] for o, _ in COLUMN_TITLES) + " |")
        for note in self.setup_notes:
            lines.append("")
            lines.append("Note: " + note)
        table = "\n".join(lines) + "\n"
        (self.out / "table.md").write_text(table)

        d = ["# Hostile campaign: cases that were not a clean error or ok", "",
             "Binary `%s`, seed %d. Each case's inputs (as they were before its first command) are in "
             "`cases/<ID>/` next to this file; run the commands from a copy of that folder with "
             "`MKTREE=%s`. `scripts/hostile.py --mktree ... --out ... --case ID` reruns one case." %
             (self.mktree, self.seed, self.mktree), ""]
        for c in self.cases:
            if c.outcome in ("ok", "clean"):
                continue
            d.append("## %s: %s (%s)" % (c.id, c.title, c.outcome))
            d.append("")
            for label, p, v, reason in c.steps:
                if v in ("ok", "clean"):
                    continue
                first = p.err.strip().splitlines()
                first = (" | ".join(first[-3:]))[:300] if first else ""
                d.append("- `%s`: %s, **%s**%s%s" % (label[:60], p.status(), v, (": " + reason) if reason else "",
                                                     ("; stderr: `%s`" % first.replace("`", "'")) if first else ""))
            for n in c.notes:
                d.append("- " + n)
            d.append("")
            d.append("```")
            d.extend(c.repro)
            d.append("```")
            d.append("")
        (self.out / "details.md").write_text("\n".join(d) + "\n")
        js = [{"id": c.id, "row": c.row, "title": c.title, "outcome": c.outcome, "notes": c.notes, "repro": c.repro,
               "steps": [{"label": l, "status": p.status(), "verdict": v, "reason": r, "stderr": p.err[-2000:]}
                         for l, p, v, r in c.steps]} for c in self.cases]
        (self.out / "cases.json").write_text(json.dumps(js, indent=1) + "\n")
        return table

    def cleanup(self):
        for m in self.mounts:
            subprocess.run(["umount", "-l", str(m)], capture_output=True)
        self.mounts = []


class SetupError(Exception):
    pass


# ---------------------------------------------------------------------------------------------------------
# 1. Corrupt stores


def CLASH_ARGS(store):
    """A self-clash that reads every leaf, and every record page (the names, for --exclude-group)."""
    return ("clash", store, "--exclude-group", "/", "--threads", "1")


def clash_check(want):
    def f(p):
        if p.out == want:
            return None
        got = [json.loads(x) for x in p.out.splitlines() if x.strip()]
        selfp = [(x["a"], x["b"]) for x in got if x.get("a") == x.get("b")]
        return "clash: %d pairs, expected %d%s" % (len(got), len(want.splitlines()),
                                                   "; objects paired with themselves %s" % selfp[:5] if selfp else "")
    return f


def cat_corrupt(h):
    num = 0
    for backend in ("hdf5", "pagefile"):
        store = h.store(backend)
        qfile = h.queries_for(h.store("pagefile"), "tanker3000.q")
        want = h.answers(store, qfile)
        want_exact = h.answers(store, qfile, exact=True)
        info_want = json.loads(h.must("info", store, "--json").out)
        clash_want = h.must(*CLASH_ARGS(store)).out
        size = store.stat().st_size
        kinds = [("flip", 40), ("truncate", 15), ("zero", 15)]
        for kind, n in kinds:
            for k in range(n):
                num += 1
                if not h.wanted("corrupt", num):
                    continue
                r = h.rng("corrupt", backend, kind, k)
                data = bytearray(store.read_bytes())
                # a third of the positions in the first 16 KiB, a third in the last 64 KiB (metadata of both
                # backends), a third anywhere
                zone = k % 3
                if zone == 0:
                    pos = r.randrange(min(size, 16384))
                elif zone == 1:
                    pos = r.randrange(max(0, size - 65536), size)
                else:
                    pos = r.randrange(size)
                if kind == "flip":
                    x = r.randrange(1, 256)
                    data[pos] ^= x
                    title = "%s: byte %d xor 0x%02x" % (backend, pos, x)
                    how = ("python3 -c \"import sys; b=bytearray(open('s.mkt','rb').read()); b[%d]^=%d; "
                           "open('s.mkt','wb').write(b)\"" % (pos, x))
                elif kind == "truncate":
                    pos = max(1, pos)
                    del data[pos:]
                    title = "%s: truncated to %d of %d bytes" % (backend, pos, size)
                    how = "truncate -s %d s.mkt" % pos
                else:
                    pos -= pos % 4096
                    data[pos:pos + 4096] = bytes(len(data[pos:pos + 4096]))
                    title = "%s: 4 KiB of zeros at %d" % (backend, pos)
                    how = "dd if=/dev/zero of=s.mkt bs=4096 seek=%d count=1 conv=notrunc" % (pos // 4096)
                c = h.new_case("corrupt", num, title)
                shutil.copyfile(qfile, c.path("q.txt"))
                c.path("s.mkt").write_bytes(data)
                c.note("pristine: $MKTREE build tanker:3000 -o s.mkt --backend %s -q; then %s" % (backend, how))
                names = ["s.mkt"]

                def info_check(p, info_want=info_want):
                    try:
                        j = json.loads(p.out)
                    except ValueError:
                        return "info --json printed invalid JSON"
                    a = {k: v for k, v in j.items() if k not in ("file", "file_bytes")}
                    b = {k: v for k, v in info_want.items() if k not in ("file", "file_bytes")}
                    return None if a == b else "info --json differs from the pristine store's"

                def q_check(w):
                    def f(p):
                        try:
                            return diff_answers(parse_answers(p.out), w)
                        except (ValueError, KeyError) as e:
                            return "unparsable query output (%s)" % e
                    return f

                c.mk("info", "s.mkt", "--json", names=names, check=info_check, protect=["s.mkt"], label="info --json")
                if not c.stopped():
                    c.mk("query", "s.mkt", "--queries", "q.txt", names=names, check=q_check(want), protect=["s.mkt"],
                         label="query")
                if not c.stopped():
                    c.mk("query", "s.mkt", "--queries", "q.txt", "--exact", names=names, check=q_check(want_exact),
                         protect=["s.mkt"], label="query --exact")
                if not c.stopped():
                    c.mk(*CLASH_ARGS("s.mkt"), names=names, check=clash_check(clash_want), protect=["s.mkt"],
                         label="clash")
                h.finish_case(c)


# ---------------------------------------------------------------------------------------------------------
# 2. Crafted stores: valid checksums, tampered structure


def _internal_pairs(m):
    """(parent, child) pairs of internal nodes whose child is internal too."""
    out = []
    for i in m.internal():
        for ch in m.nodes[i][8:10]:
            if ch < len(m.nodes) and m.nodes[ch][12] < 3:
                out.append((i, ch))
    return out


def _deep_internal(m, r):
    cand = [i for i in m.internal() if i != 0 and m.depth_of(i) >= 2]
    return r.choice(cand)


def mut_cycle_to_root(m, r):
    x = _deep_internal(m, r)
    n = m.node(x)
    n["c"][0] = 0
    m.set_node(x, n)
    return "node %d's first child is the root (a cycle)" % x


def mut_cycle_two(m, r):
    p, ch = r.choice([pc for pc in _internal_pairs(m) if pc[0] != 0] or _internal_pairs(m))
    n = m.node(ch)
    n["c"][1] = p
    m.set_node(ch, n)
    return "node %d's second child is its parent %d (a two-node cycle)" % (ch, p)


def mut_shared_child(m, r):
    ints = m.internal()
    for _ in range(200):
        x, y = r.sample(ints, 2)
        if y not in m.subtree(x) and x not in m.subtree(y):
            break
    n = m.node(x)
    old = n["c"][0]
    n["c"][0] = m.node(y)["c"][0]
    m.set_node(x, n)
    return "node %d's first child is node %d's (%d reached twice, subtree of %d orphaned)" % (x, y, n["c"][0], old)


def mut_both_children_same(m, r):
    x = r.choice(m.internal())
    n = m.node(x)
    n["c"][1] = n["c"][0]
    m.set_node(x, n)
    return "node %d has the same node as both children" % x


def mut_orphan_leaf_node(m, r):
    src = r.choice(m.leaf_nodes())
    m.nodes.append(m.nodes[src])
    return "a copy of leaf node %d appended, unreachable (its leaf referenced twice)" % src


def mut_orphan_internal(m, r):
    a, b = r.sample(m.leaf_nodes(), 2)
    n = m.node(0)
    n["c"] = [a, b]
    n["split"] = NO_INDEX
    m.nodes.append(m.node_tuple(n))
    return "an unreachable internal node appended over leaf nodes %d and %d" % (a, b)


def mut_leaf_twice(m, r):
    a, b = r.sample(m.leaf_nodes(), 2)
    na, nb = m.node(a), m.node(b)
    lost = na["leaf"]
    na["leaf"] = nb["leaf"]
    m.set_node(a, na)
    return "leaf nodes %d and %d both reference leaf %d (leaf %d unreferenced)" % (a, b, nb["leaf"], lost)


def mut_leaf_backref(m, r):
    i = r.randrange(len(m.leaves))
    l = m.leaf(i)
    l["node"] = r.choice([j for j in m.leaf_nodes() if j != l["node"]])
    m.set_leaf(i, l)
    return "leaf %d's record names node %d, which is not its node" % (i, l["node"])


def mut_object_two_leaves(m, r):
    k = r.randrange(len(m.obj_leaf))
    old = m.obj_leaf[k]
    new = r.choice([i for i in range(len(m.leaves)) if i != old])
    if m.version >= 5:  # the leaf is a field of the object's record: read by `render --focus` (ObjectLeaf)
        pi = m.set_record_leaf(k, new)
        m.check_objects = [k]
        return "object %d's record (page %d, resealed) says leaf %d; its entry is in leaf %d" % (k, pi, new, old)
    m.obj_leaf[k] = new
    return "object %d's table entry says leaf %d; its page is in leaf %d" % (k, m.obj_leaf[k], old)


def mut_record_leaf_range(m, r):
    if m.version < 5:
        raise ValueError("format 5 only")
    k = r.randrange(m.object_count)
    bad = r.choice([len(m.leaves), len(m.leaves) + 7, 0xFFFFFFFF])
    pi = m.set_record_leaf(k, bad)
    m.check_objects = [k]
    return "object %d's record (page %d, resealed) says leaf %d (%d leaves)" % (k, pi, bad, len(m.leaves))


def mut_digest_swap(m, r):
    if m.version < 5:
        raise ValueError("format 5 only")
    i, j = r.sample(range(len(m.leaves)), 2)
    m.digests[i], m.digests[j] = m.digests[j], m.digests[i]
    return [i, j], "leaves %d and %d's id digests swapped (the digests still add up)" % (i, j)


def mut_digest_total(m, r):
    if m.version < 5:
        raise ValueError("format 5 only")
    i = r.randrange(len(m.leaves))
    m.digests[i] = (m.digests[i] + 1) & MASK64
    return "leaf %d's id digest +1 (the digests no longer add up)" % i


def mut_count_total(m, r):
    i = r.randrange(len(m.leaves))
    a = m.leaf(i)
    a["count"] += 1
    m.set_leaf(i, a)
    return "leaf %d's object count +1 (the counts no longer add up to the object count)" % i


def mut_digest_move(m, r):
    # Object k's id moves from its leaf's digest to another's, counts too: digests and counts add up,
    # each leaf's record is consistent with the other, but the entries are not where the digests say.
    if m.version < 5:
        raise ValueError("format 5 only")
    k = r.randrange(m.object_count)
    i = m.obj_leaf[k]
    j = r.choice([x for x in range(len(m.leaves)) if x != i])
    m.digests[i] = (m.digests[i] - id_hash(k)) & MASK64
    m.digests[j] = (m.digests[j] + id_hash(k)) & MASK64
    a, b = m.leaf(i), m.leaf(j)
    a["count"] -= 1
    b["count"] += 1
    m.set_leaf(i, a)
    m.set_leaf(j, b)
    return [i, j], "object %d's id digest and count moved from leaf %d to leaf %d (its entry stays)" % (k, i, j)


def mut_count_shift(m, r):
    i, j = r.sample(range(len(m.leaves)), 2)
    a, b = m.leaf(i), m.leaf(j)
    a["count"] += 1
    b["count"] -= 1
    m.set_leaf(i, a)
    m.set_leaf(j, b)
    return "leaf %d's object count +1 and leaf %d's -1 (the total still agrees)" % (i, j)


def mut_pages_overlap(m, r):
    i, j = r.sample(range(len(m.leaves)), 2)
    a = m.leaf(i)
    a["first"] = m.leaf(j)["first"]
    m.set_leaf(i, a)
    return "leaf %d's first page is leaf %d's page %d (two leaves on one page)" % (i, j, a["first"])


def mut_page_count(m, r):
    i = r.choice([i for i in range(len(m.leaves)) if m.leaf(i)["first"] + 2 <= len(m.pages_list())])
    a = m.leaf(i)
    a["pages"] = 2
    m.set_leaf(i, a)
    return "leaf %d's record says 2 pages (the next leaf's page is the second)" % i


def mut_payload_bytes(m, r):
    i = r.randrange(len(m.leaves))
    a = m.leaf(i)
    a["payload"] += 8
    m.set_leaf(i, a)
    return i, "leaf %d's payload bytes +8" % i  # found when the leaf is read: the queries read it


def mut_depth_lie(m, r):
    for i in range(len(m.nodes)):
        n = m.node(i)
        n["depth"] = 0
        m.set_node(i, n)
    return "every node's depth field 0"


def _chain(m, depth, both):
    root = m.node(0)
    d = depth
    shifted = []
    for t in m.nodes:
        v = list(t)
        if v[12] < 3:
            v[8] += d
            v[9] += d
        shifted.append(tuple(v))
    chain = []
    for i in range(d):
        n = dict(root)
        n["box"] = list(root["box"])
        nxt = i + 1
        n["c"] = [nxt, nxt] if both else [nxt, d]
        n["split"] = NO_INDEX
        n["a"], n["b"] = root["box"][0], root["box"][0]  # no overlap slab
        n["axis"] = 0
        n["depth"] = min(i, 255)
        chain.append(m.node_tuple(n))
    m.nodes = chain + shifted
    for i in range(len(m.leaves)):
        l = m.leaf(i)
        l["node"] += d
        m.set_leaf(i, l)


def mut_chain(m, r):
    _chain(m, 10000, both=False)
    return "10,000 internal nodes in a chain above the root, each also pointing at the old root"


def mut_chain_dag(m, r):
    _chain(m, 10000, both=True)
    return "10,000 internal nodes in a chain, both children of each the next one (2^10000 paths)"


def mut_split_cycle(m, r):
    roots = [m.node(i)["split"] for i in m.internal() if m.node(i)["split"] != NO_INDEX]
    inner = [s for s in roots if m.splits[s][3] < 3]
    s = r.choice(inner)
    v = list(m.splits[s])
    ch = v[1]
    if m.splits[ch][3] < 3:
        w = list(m.splits[ch])
        w[1] = s
        m.splits[ch] = tuple(w)
        return "split node %d's child %d points back at it (a SplitTree cycle)" % (s, ch)
    v[2] = s
    m.splits[s] = tuple(v)
    return "split node %d is its own child" % s


def mut_split_shared(m, r):
    with_split = [i for i in m.internal() if m.node(i)["split"] != NO_INDEX]
    a, b = r.sample(with_split, 2)
    na = m.node(a)
    na["split"] = m.node(b)["split"]
    m.set_node(a, na)
    return "nodes %d and %d share one SplitTree" % (a, b)


def mut_table_short(m, r):
    # Drop the last object from the object table (and its leaf's count): its entry stays in a page.
    k = len(m.obj_leaf) - 1
    li = m.obj_leaf.pop()
    if m.version >= 5:  # keep the digests adding up to AllIdsDigest(N - 1): only the page read finds it
        m.digests[li] = (m.digests[li] - id_hash(k)) & MASK64
    if m.names is not None:
        m.names.pop()
    m.object_count -= 1
    l = m.leaf(li)
    l["count"] -= 1
    m.set_leaf(li, l)
    f = m.leaf_filter
    del f[len(f) - 8:]
    return "object %d dropped from the object table and its leaf's count; its entry is still in leaf %d" % (k, li)


def mut_empty_nodes(m, r):
    m.nodes = []
    return "no nodes at all, leaves and objects kept"


def mut_stats_inject(m, r):
    s = m.stats.decode()
    m.stats = ('{"injected_key": "evil", "file": "forged.mkt", ' + s[1:]).encode()
    return "stats JSON with injected keys injected_key and file"


def mut_stats_breakout(m, r):
    m.stats = b'1, "injected": {"x": 1}, "objects": 999999'
    return "stats JSON that closes the tree value and adds keys"


def mut_stats_invalid(m, r):
    m.stats = b'{"objects": 3000, "levels": [{"depth": '
    return "stats JSON cut short (invalid JSON)"


def mut_stats_controls(m, r):
    m.stats = b'{"objects": 3000, "name": "a\nb\x01\x7f\xff\xfe"}'
    return "stats JSON with a raw newline, control bytes and invalid UTF-8 in a string"


def mut_stats_deep(m, r):
    m.stats = b"[" * 100000 + b"]" * 100000
    return "stats JSON nested 100,000 levels deep"


# semantic tampering: consistent structure, wrong content
def mut_label_flip(m, r):
    cells = [i for i, s in enumerate(m.splits) if s[3] == 3 and s[4] in (1, 2)]
    pick = r.sample(cells, min(len(cells), max(1, len(cells) // 3)))
    for i in pick:
        v = list(m.splits[i])
        v[4] = 3 - v[4]
        m.splits[i] = tuple(v)
    return "%d SplitTree cells LEFT and RIGHT swapped" % len(pick)


def mut_node_box_shrink(m, r):
    x = r.choice(m.internal())
    n = m.node(x)
    b = n["box"]
    n["box"] = ([b[i] + (b[i + 3] - b[i]) * 0.4 for i in range(3)] +
                [b[i + 3] - (b[i + 3] - b[i]) * 0.4 for i in range(3)])
    m.set_node(x, n)
    return "internal node %d's box shrunk to its middle fifth" % x


def mut_slab_moved(m, r):
    x = r.choice(m.internal())
    n = m.node(x)
    ax = n["axis"]
    w = n["box"][ax + 3] - n["box"][ax]
    n["a"], n["b"] = n["a"] + 0.3 * w, n["b"] - 0.3 * w
    m.set_node(x, n)
    return "internal node %d's planes a, b moved 30 %% of its width" % x


def mut_filter_zero(m, r):
    for i in range(0, len(m.leaf_filter), 8):
        m.leaf_filter[i:i + 8] = bytes(8)
    return "every leaf-filter entry a point at its leaf's minimum corner"


def mut_leaf_box_shrink(m, r):
    i = r.randrange(len(m.leaves))
    l = m.leaf(i)
    b = l["box"]
    l["box"] = ([b[k] + (b[k + 3] - b[k]) * 0.45 for k in range(3)] +
                [b[k + 3] - (b[k + 3] - b[k]) * 0.45 for k in range(3)])
    m.set_leaf(i, l)
    return "leaf %d's box shrunk to its middle tenth" % i


# page reseals: valid page checksums, tampered entries
def _leaf_with(m, r, n=2):
    return r.choice([i for i in range(len(m.leaves)) if m.leaf(i)["pages"] == 1 and m.leaf(i)["count"] >= n])


def pg_dup_id(m, r):
    li = _leaf_with(m, r)
    es = m.leaf_entries(li)
    first = es[0][0][0]
    k = r.randrange(1, len(es))
    b = bytearray(es[k][1])
    struct.pack_into("<I", b, 0, first)
    raws = [e[1] for e in es]
    raws[k] = bytes(b)
    m.reseal(m.leaf(li)["first"], li, raws)
    return li, "leaf %d: entry %d's id set to entry 0's id %d (a duplicated id), page resealed" % (li, k, first)


def pg_foreign_id(m, r):
    li = _leaf_with(m, r)
    es = m.leaf_entries(li)
    other = r.choice([i for i in range(len(m.obj_leaf)) if m.obj_leaf[i] != li])
    k = r.randrange(len(es))
    b = bytearray(es[k][1])
    old = struct.unpack_from("<I", b, 0)[0]
    struct.pack_into("<I", b, 0, other)
    raws = [e[1] for e in es]
    raws[k] = bytes(b)
    m.reseal(m.leaf(li)["first"], li, raws)
    return li, "leaf %d: entry %d's id %d replaced by object %d of leaf %d, page resealed" % (
        li, k, old, other, m.obj_leaf[other])


def pg_transplant(m, r):
    for _ in range(100):
        li, lj = r.sample(range(len(m.leaves)), 2)
        ei, ej = m.leaf_entries(li), m.leaf_entries(lj)
        pick = r.choice(ej)
        raws = [e[1] for e in ei] + [pick[1]]
        if 16 + sum(len(x) for x in raws) <= m.P - 32:
            break
    payload = m.reseal(m.leaf(li)["first"], li, raws)
    l = m.leaf(li)
    l["payload"] = payload
    m.set_leaf(li, l)
    return li, "object %d of leaf %d copied into leaf %d's page too (in two leaves), page and leaf record resealed" % (
        pick[0][0], lj, li)


def pg_id_range(m, r):
    li = _leaf_with(m, r)
    es = m.leaf_entries(li)
    k = r.randrange(len(es))
    b = bytearray(es[k][1])
    struct.pack_into("<I", b, 0, len(m.obj_leaf) + 5)
    raws = [e[1] for e in es]
    raws[k] = bytes(b)
    m.reseal(m.leaf(li)["first"], li, raws)
    return li, "leaf %d: entry %d's id set to %d (past the object table), page resealed" % (li, k, len(m.obj_leaf) + 5)


def pg_tri_index(m, r):
    li = _leaf_with(m, r)
    es = m.leaf_entries(li)
    k = r.randrange(len(es))
    e, raw = es[k]
    if e[7] != 0:  # codec: only a raw entry can be edited in place
        raise ValueError("entry is compressed")
    nv, nt = e[11], e[12]
    b = bytearray(raw)
    struct.pack_into("<I", b, 48 + 12 * nv + 4 * r.randrange(3 * nt), 50000000)
    raws = [x[1] for x in es]
    raws[k] = bytes(b)
    m.reseal(m.leaf(li)["first"], li, raws)
    return li, "leaf %d: object %d's triangle index set to 50,000,000 (%d vertices), page resealed" % (li, e[0], nv)


def pg_vertex_nan(m, r):
    li = _leaf_with(m, r)
    es = m.leaf_entries(li)
    k = r.randrange(len(es))
    e, raw = es[k]
    if e[7] != 0:
        raise ValueError("entry is compressed")
    b = bytearray(raw)
    struct.pack_into("<f", b, 48 + 4 * r.randrange(3 * e[11]), float("nan"))
    raws = [x[1] for x in es]
    raws[k] = bytes(b)
    m.reseal(m.leaf(li)["first"], li, raws)
    return li, "leaf %d: a vertex coordinate of object %d set to NaN, page resealed" % (li, e[0])


def pg_counts_bomb(m, r):
    li = _leaf_with(m, r)
    es = m.leaf_entries(li)
    k = r.randrange(len(es))
    b = bytearray(es[k][1])
    nv = 100_000_000
    struct.pack_into("<III", b, 32, nv, 1, 12 * (nv + 1))
    raws = [x[1] for x in es]
    raws[k] = bytes(b)
    m.reseal(m.leaf(li)["first"], li, raws)
    return li, "leaf %d: entry %d claims 100,000,000 vertices (1.2 GB raw), page resealed" % (li, k)


def pg_box_away(m, r):
    li = _leaf_with(m, r)
    es = m.leaf_entries(li)
    k = r.randrange(len(es))
    b = bytearray(es[k][1])
    box = list(struct.unpack_from("<6f", b, 4))
    box = [v + 1000.0 for v in box]
    struct.pack_into("<6f", b, 4, *box)
    raws = [x[1] for x in es]
    raws[k] = bytes(b)
    m.reseal(m.leaf(li)["first"], li, raws)
    return li, "leaf %d: entry %d's box moved 1000 units outside its leaf, page resealed" % (li, k)


def _fpylll():
    try:
        import fpylll
        return fpylll
    except ImportError:
        subprocess.run(["apt-get", "install", "-y", "-q", "python3-fpylll"], capture_output=True, text=True)
    try:
        import fpylll
        return fpylll
    except ImportError:
        raise ValueError("python3-fpylll (lattice reduction) is not installed and apt-get could not install it")


def _box_within(a, b):
    return all(b[i] <= a[i] and a[i + 3] <= b[i + 3] for i in range(3))


def mut_digest_collision(m, r):
    """A crafted digest collision (docs/store_format.md: the digest is a checksum, not a proof).

    Finds c in {-1, 0, 1}^n, sum c = 0, sum c_i ObjectIdHash(id_i) = 0 mod 2^64 over n objects that each fit
    another leaf's box (LLL + BKZ on the knapsack lattice), then copies each c = +1 object into such a leaf
    and deletes each c = -1 object from its own. Counts and digests (recomputed per leaf) add up and every
    entry lies in its leaf's box, so only the ids differ: some listed twice, as many missing."""
    if m.version < 5:
        raise ValueError("format 5 only")
    fpylll = _fpylll()
    entries = {li: m.leaf_entries(li) for li in range(len(m.leaves)) if m.leaf(li)["pages"] == 1}
    own, raw, hosts = {}, {}, {}
    for li, es in entries.items():
        for e, rb in es:
            own[e[0]], raw[e[0]] = li, rb
    for oid, li in own.items():
        box = ENTRY.unpack_from(raw[oid], 0)[1:7]
        hs = [lj for lj in entries if lj != li and _box_within(box, m.leaf(lj)["box"])]
        if hs:
            hosts[oid] = hs
    room0 = {li: m.P - 32 - m.leaf(li)["payload"] for li in entries}
    hosts = {oid: [lj for lj in hs if room0[lj] >= len(raw[oid])] for oid, hs in hosts.items()}
    hosts = {oid: hs for oid, hs in hosts.items() if hs}  # a leaf with room for it too
    if len(hosts) < 40:
        raise ValueError("only %d objects fit another leaf's box and page" % len(hosts))
    for attempt in range(8):
        ids = r.sample(sorted(hosts), min(60, len(hosts)))
        n, K = len(ids), 1 << 20
        rows = [[int(k == j) for j in range(n)] + [K * id_hash(i), K] for k, i in enumerate(ids)]
        rows.append([0] * n + [K << 64, 0])
        A = fpylll.IntegerMatrix.from_matrix(rows)
        fpylll.LLL.reduction(A)
        fpylll.BKZ.reduction(A, fpylll.BKZ.Param(20))
        vecs = []
        for row in range(A.nrows):
            v = [A[row, j] for j in range(n + 2)]
            if v[n] == 0 and v[n + 1] == 0 and any(v[:n]) and max(abs(x) for x in v[:n]) == 1:
                vecs.append(v[:n])
        vecs.sort(key=lambda v: sum(abs(x) for x in v))
        for v in vecs:
            for sign in (1, -1):
                c = {ids[k]: sign * v[k] for k in range(n) if v[k]}
                room, add, drop = dict(room0), {}, {}
                for oid, x in c.items():
                    if x < 0:
                        drop.setdefault(own[oid], set()).add(oid)
                        room[own[oid]] += len(raw[oid])
                ok = True
                for oid, x in sorted(c.items()):
                    if x < 0:
                        continue
                    h = [lj for lj in hosts[oid] if room[lj] >= len(raw[oid]) and oid not in add.get(lj, ())]
                    if not h:
                        ok = False
                        break
                    lj = h[0]
                    add.setdefault(lj, []).append(oid)
                    room[lj] -= len(raw[oid])
                if not ok or any(len(entries[li]) - len(d) + len(add.get(li, ())) < 1 for li, d in drop.items()):
                    continue
                changed = sorted(set(add) | set(drop))
                for li in changed:
                    keep = [rb for e, rb in entries[li] if e[0] not in drop.get(li, ())]
                    keep += [raw[oid] for oid in add.get(li, ())]
                    ids_li = [struct.unpack_from("<I", rb, 0)[0] for rb in keep]
                    payload = m.reseal(m.leaf(li)["first"], li, keep)
                    lr = m.leaf(li)
                    lr["count"], lr["payload"] = len(keep), payload
                    m.set_leaf(li, lr)
                    m.digests[li] = sum(id_hash(i) for i in ids_li) & MASK64
                m.leaf_filter = bytearray()  # its entries follow the leaves' payload order; empty = no filter
                dup = sorted(o for o, x in c.items() if x > 0)
                miss = sorted(o for o, x in c.items() if x < 0)
                m.extra_points = []
                for oid in dup + miss:
                    b = ENTRY.unpack_from(raw[oid], 0)[1:7]
                    m.extra_points.append([(b[i] + b[i + 3]) / 2 + m.origin[i] for i in range(3)])
                # Queries that meet the deleted ids alone (their centres): nothing there is read twice.
                m.alone_points = m.extra_points[len(dup):]
                return changed, ("a crafted id digest collision: objects %s each copied into a second leaf, "
                                 "objects %s deleted, leaves %s resealed (digests recomputed, they add up), "
                                 "leaf filter emptied" % (dup, miss, changed))
    raise ValueError("no collision found that fits the leaves' pages")


def _dictionary(m):
    if getattr(m, "dictionary", None) is None or len(m.dictionary) < 16:
        raise ValueError("paged-file stores of format 6 with a codec dictionary only")
    return m.dictionary


def mut_dict_magic(m, r):
    d = _dictionary(m)
    d[0:4] = bytes(4)  # no longer a zstd dictionary: zstd would take it as raw content
    return "codec dictionary magic zeroed (section checksum recomputed)"


def mut_dict_truncated(m, r):
    d = _dictionary(m)
    del d[8 + r.randrange(8):]  # magic and id kept, entropy tables cut
    return "codec dictionary cut to %d bytes (section checksum recomputed)" % len(d)


STRUCT_MUTS = [mut_cycle_to_root, mut_cycle_two, mut_shared_child, mut_both_children_same, mut_orphan_leaf_node,
               mut_orphan_internal, mut_leaf_twice, mut_leaf_backref, mut_object_two_leaves, mut_count_shift,
               mut_pages_overlap, mut_page_count, mut_payload_bytes, mut_depth_lie, mut_chain, mut_chain_dag,
               mut_split_cycle, mut_split_shared, mut_table_short, mut_empty_nodes]
# format 5: the leaf id digests and the record's leaf field (after the others, so that their case ids stay)
F5_MUTS = [mut_record_leaf_range, mut_digest_swap, mut_digest_total, mut_count_total, mut_digest_move]
F5_SEMANTIC_MUTS = [mut_digest_collision]
# format 6: the codec dictionary section (after the others, so that their case ids stay)
F6_MUTS = [mut_dict_magic, mut_dict_truncated]
STATS_MUTS = [mut_stats_inject, mut_stats_breakout, mut_stats_invalid, mut_stats_controls, mut_stats_deep]
SEMANTIC_MUTS = [mut_label_flip, mut_node_box_shrink, mut_slab_moved, mut_filter_zero, mut_leaf_box_shrink]
PAGE_MUTS = [pg_dup_id, pg_foreign_id, pg_transplant, pg_id_range, pg_tri_index, pg_vertex_nan, pg_counts_bomb]
SEMANTIC_PAGE_MUTS = [pg_box_away]


def _pages_list(self):
    return self.pages if hasattr(self, "pages") else list(range(self.page_count))


Model.pages_list = _pages_list


def cat_crafted(h):
    err = need_h5py()
    backends = ["pagefile"] + (["hdf5"] if err is None else [])
    if err:
        h.setup_notes.append("crafted HDF5 stores skipped: " + err)
    num = 0
    groups = [("s", f, "crafted") for f in STRUCT_MUTS] + [("j", f, "crafted") for f in STATS_MUTS] + \
             [("p", f, "crafted") for f in PAGE_MUTS] + [("s", f, "crafted-semantic") for f in SEMANTIC_MUTS] + \
             [("p", f, "crafted-semantic") for f in SEMANTIC_PAGE_MUTS] + \
             [("s", f, "crafted") for f in F5_MUTS] + [("s", f, "crafted-semantic") for f in F5_SEMANTIC_MUTS] + \
             [("s", f, "crafted") for f in F6_MUTS]
    for backend in ("pagefile", "hdf5"):
        if backend not in backends:
            num += len(groups)
            continue
        base = {"zstd": h.store(backend), "none": h.store(backend, extra=("--codec", "none"))}
        qbase = h.queries_for(h.store("pagefile"), "tanker3000.q")
        for kind, fn, row in groups:
            num += 1
            if not h.wanted("crafted", num):
                continue
            codec = "none" if fn in (pg_tri_index, pg_vertex_nan) else "zstd"
            src = base[codec]
            r = h.rng("crafted", backend, fn.__name__)
            c = h.new_case("crafted", num, "%s: %s" % (backend, fn.__name__), row=row)
            tmp = c.path("s.mkt")
            shutil.copyfile(src, tmp)
            m = load_model(str(tmp))
            extra_q = []
            try:
                res = fn(m, r)
            except (ValueError, IndexError) as e:
                h.setup_notes.append("crafted %s %s not applicable: %s" % (backend, fn.__name__, e))
                shutil.rmtree(c.dir)
                continue
            if isinstance(res, tuple):  # tampered leaves, found when they are read
                lis, what = res
                pm = load_model(str(src))
                o = pm.origin
                for li in (lis if isinstance(lis, list) else [lis]):
                    # A box over the tampered leaf (world coordinates) so that the page is read.
                    b = pm.leaf(li)["box"]
                    extra_q.append([b[i] + o[i] for i in range(3)] + [b[i + 3] + o[i] for i in range(3)])
                    for e, _ in pm.leaf_entries(li)[:4]:
                        extra_q.append([(e[1 + i] + e[4 + i]) / 2 + o[i] for i in range(3)])
                extra_q += getattr(m, "extra_points", [])
            else:
                what = res
            m.save(str(tmp))
            c.title = "%s: %s" % (backend, what)
            qtext = qbase.read_text()
            qf = c.path("q.txt")
            write_queries(qf, extra_q)
            qf.write_text(qtext + "".join(qf.read_text().splitlines(True)[1:]))
            pristine = c.dir / "pristine.mkt"
            shutil.copyfile(src, pristine)
            want = parse_answers(h.must("query", pristine, "--queries", qf).out)
            want_exact = parse_answers(h.must("query", pristine, "--queries", qf, "--exact").out)
            alone_want = None
            if getattr(m, "alone_points", None):
                write_queries(c.path("q_alone.txt"), m.alone_points)
                alone_want = parse_answers(h.must("query", pristine, "--queries", c.path("q_alone.txt")).out)
            clash_want = h.must(*CLASH_ARGS(pristine)).out if kind != "j" else None
            # collide with a box around the whole scene: every object once
            lo, hi = json.loads(h.must("info", pristine, "--json").out)["bounds"]
            corners = [[(hi if (v >> i) & 1 else lo)[i] + (1 if (v >> i) & 1 else -1) for i in range(3)]
                       for v in range(8)]
            c.path("all.obj").write_text("o all\n" + "".join("v %r %r %r\n" % tuple(p) for p in corners) + "".join(
                "f %d %d %d\n" % (a + 1, b + 1, d + 1) for a, b, d in
                [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4), (2, 6, 7), (2, 7, 3), (0, 4, 6),
                 (0, 6, 2), (1, 3, 7), (1, 7, 5)]))
            collide_want = h.must("collide", pristine, "--object", c.path("all.obj"), "--threads", "1").out
            rec_want = []
            for k in getattr(m, "check_objects", []):
                other = 1 if k != 1 else 2
                pairs = c.path("p%d.jsonl" % k)
                pairs.write_text('{"a": %d, "b": %d, "class": "hard"}\n' % (min(k, other), max(k, other)))
                info = h.must("info", pristine, "--object", k, "--json").out
                png = c.dir / "pristine.png"
                h.must("render", pristine, "--clashes", pairs, "--focus", 1, "--size", "240x200", "-o", png, "-q")
                rec_want.append((k, pairs.name, info, png.read_bytes()))
                png.unlink()
            pristine.unlink()
            c.note("made by scripts/hostile.py (crafted, %s) from: $MKTREE build tanker:3000 -o s.mkt --backend %s -q%s"
                   % (fn.__name__, backend, " --codec none" if codec == "none" else ""))
            names = ["s.mkt"]

            def q_check(w):
                def f(p):
                    try:
                        return diff_answers(parse_answers(p.out), w)
                    except (ValueError, KeyError) as e:
                        return "unparsable query output (%s)" % e
                return f

            c.mk("info", "s.mkt", "--json", names=names, check=lambda p: check_info_json(p.out), protect=["s.mkt"],
                 label="info --json")
            if kind != "j":
                if not c.stopped():
                    c.mk("query", "s.mkt", "--queries", "q.txt", names=names, check=q_check(want), protect=["s.mkt"],
                         label="query")
                if not c.stopped():
                    c.mk("query", "s.mkt", "--queries", "q.txt", "--exact", names=names, check=q_check(want_exact),
                         protect=["s.mkt"], label="query --exact")
                if not c.stopped():
                    c.mk(*CLASH_ARGS("s.mkt"), names=names, check=clash_check(clash_want), protect=["s.mkt"],
                         label="clash")
                if not c.stopped():
                    c.mk("collide", "s.mkt", "--object", "all.obj", "--threads", "1", names=names, protect=["s.mkt"],
                         check=lambda p, w=collide_want: None if p.out == w else "collide: %d lines, expected %d" % (
                             len(p.out.splitlines()), len(w.splitlines())), label="collide")
                if alone_want is not None and not c.stopped():
                    c.mk("query", "s.mkt", "--queries", "q_alone.txt", names=names, check=q_check(alone_want),
                         protect=["s.mkt"], label="query (deleted ids alone)")
                for k, pairs, info, png in rec_want:
                    if c.stopped():
                        break
                    c.mk("info", "s.mkt", "--object", k, "--json", names=names, protect=["s.mkt"],
                         check=lambda p, info=info: None if p.out == info else "info --object differs: %r, expected %r"
                         % (p.out[:200], info[:200]), label="info --object %d" % k)
                    c.mk("render", "s.mkt", "--clashes", pairs, "--focus", 1, "--size", "240x200", "-o", "o.png", "-q",
                         names=names, protect=["s.mkt"], outputs=["o.png"],
                         check=lambda p, png=png: None if c.path("o.png").read_bytes() == png else
                         "render --focus: a different image than the pristine store's", label="render --focus %d" % k)
            h.finish_case(c, require_error=(kind != "j" and row == "crafted"))


# ---------------------------------------------------------------------------------------------------------
# 3. Malformed scenes


def obj_mutate(text, r):
    lines = text.split("\n")
    edits = []
    for _ in range(r.choice([1, 1, 2, 3])):
        kind = r.choice(["del", "dup", "swap", "num", "num", "idx", "idx", "garbage", "byte", "trunc", "face2",
                         "longline", "emptyname"])
        body = [i for i, l in enumerate(lines) if l and not l.startswith("#")]
        if kind == "del":
            i = r.choice(body)
            edits.append("deleted line %d %r" % (i + 1, lines[i][:30]))
            del lines[i]
        elif kind == "dup":
            i = r.choice(body)
            lines.insert(i, lines[i])
            edits.append("duplicated line %d" % (i + 1))
        elif kind == "swap":
            i, j = r.sample(body, 2)
            lines[i], lines[j] = lines[j], lines[i]
            edits.append("swapped lines %d and %d" % (i + 1, j + 1))
        elif kind == "num":
            vi = [i for i in body if lines[i].startswith("v ")]
            i = r.choice(vi)
            t = lines[i].split()
            k = r.randrange(1, len(t))
            t[k] = r.choice(["nan", "inf", "-inf", "1e39", "-1e39", "1e308", "", "abc", "0x1p3", "1e-320", "-0",
                             "99999999999999999999", "1.5.2", "1e", "+", "NaN"])
            lines[i] = " ".join(t)
            edits.append("line %d is now %r" % (i + 1, lines[i][:40]))
        elif kind == "idx":
            fi = [i for i in body if lines[i].startswith("f ")]
            i = r.choice(fi)
            t = lines[i].split()
            k = r.randrange(1, len(t))
            t[k] = r.choice(["0", "999", "-999", "-1", "4294967297", "1/2", "1//3", "a", "1/1/1/1", "-0",
                             "18446744073709551617"])
            lines[i] = " ".join(t)
            edits.append("line %d is now %r" % (i + 1, lines[i]))
        elif kind == "garbage":
            i = r.randrange(len(lines))
            g = "".join(chr(r.randrange(32, 127)) for _ in range(r.randrange(1, 40)))
            lines.insert(i, g)
            edits.append("inserted line %d %r" % (i + 1, g))
        elif kind == "byte":
            s = "\n".join(lines)
            pos = r.randrange(len(s))
            ch = chr(r.choice([0, 9, 13, 32, 45, 46, 47, 48, 101, 102, 111, 118, 255, 127]))
            s = s[:pos] + ch + s[pos + 1:]
            lines = s.split("\n")
            edits.append("byte %d set to 0x%02x" % (pos, ord(ch)))
        elif kind == "trunc":
            s = "\n".join(lines)
            pos = r.randrange(len(s) // 2, len(s))
            lines = s[:pos].split("\n")
            edits.append("truncated at byte %d" % pos)
        elif kind == "face2":
            fi = [i for i in body if lines[i].startswith("f ")]
            i = r.choice(fi)
            t = lines[i].split()
            lines[i] = " ".join(t[:r.choice([1, 2, 3])]) if r.random() < 0.5 else lines[i] + " 1" * 200
            edits.append("line %d now has %d tokens" % (i + 1, len(lines[i].split())))
        elif kind == "longline":
            i = r.randrange(len(lines))
            lines.insert(i, "# " + "9" * 200000)
            edits.append("a 200 KB comment line at %d" % (i + 1))
        elif kind == "emptyname":
            oi = [i for i in body if lines[i].startswith("o ")]
            i = r.choice(oi)
            lines[i] = "o"
            edits.append("line %d is a bare `o`" % (i + 1))
    return "\n".join(lines), "; ".join(edits)


def scene_checks(h, c, store, objs=None, exact_points=None):
    """After a successful build: the store opens, a box over everything returns 0..N-1 once each, and (objs
    given: the reference reading's [(name, box)]) N matches and every object's box centre hits it."""
    p = c.mk("info", store, "--json", expect="succeed", names=[store], label="info --json (after build)")
    if p != "ok":
        if p == "unclean":
            label, pr, _, reason = c.steps[-1]
            c.steps[-1] = (label, pr, "wrong", "the build exited 0 but its store does not open")
        return
    try:
        n = json.loads(c.steps[-1][1].out)["objects"]
    except (ValueError, KeyError):
        c.record("info", c.steps[-1][1], "wrong", "info --json unreadable after build")
        return
    qs = [[-1e30, -1e30, -1e30, 1e30, 1e30, 1e30]]
    if objs:
        qs += [[(b[0][i] + b[1][i]) / 2 for i in range(3)] for _, b in objs]
    write_queries(c.path("chk.q"), qs)

    def check(p):
        try:
            a = parse_answers(p.out)
        except (ValueError, KeyError) as e:
            return "unparsable query output (%s)" % e
        if a[0][2] != list(range(n)):
            return "a box over everything returns %d ids (%s...), expected 0..%d once each" % (
                len(a[0][2]), a[0][2][:5], n - 1)
        if objs is not None:
            if n != len(objs):
                return "the store holds %d objects, the file has %d" % (n, len(objs))
            for k in range(len(objs)):
                if k not in a[k + 1][2]:
                    return "object %d (%r) not found at its box centre" % (k, objs[k][0])
        return None
    c.mk("query", store, "--queries", "chk.q", expect="succeed", names=[store], check=check, label="query (checks)")


def cat_scenes(h):
    num = 0
    base = cube_obj(TINY_CUBES)

    def case(title):
        nonlocal num
        num += 1
        if not h.wanted("scenes", num):
            return None
        return h.new_case("scenes", num, title)

    # 3a. random edits of a small valid OBJ
    for k in range(40):
        r = h.rng("scenes", "objmut", k)
        text, what = obj_mutate(base, r)
        c = case("OBJ edit: " + what)
        if c is None:
            continue
        c.path("m.obj").write_bytes(text.encode("latin-1", "replace"))
        shutil.copyfile(h.store("pagefile"), c.path("s.mkt"))
        verdict, objs = ref_parse_obj(text)
        expect = {"valid": "either", "invalid": "fail", "junk": "either"}[verdict]
        c.note("reference reading: " + verdict)
        res = c.mk("build", "m.obj", "-o", "s.mkt", "--backend", "pagefile", "-q", expect=expect, names=["m.obj"],
                   protect=["m.obj"], prev=["s.mkt"], outputs=["s.mkt"], warn_ok=False,
                   label="build m.obj")
        if res == "ok":
            scene_checks(h, c, "s.mkt", objs if verdict == "valid" else None)
        elif res in ("clean",) and verdict == "valid":
            c.steps[-1] = c.steps[-1][:2] + ("wrong", "refused a valid file")
        h.finish_case(c)

    # 3b. specific hostile scenes, each with a previous good store at the output path
    def build_case(title, files, scene, expect, backend="pagefile", objs=None, names=None, warn_ok=True, extra=()):
        c = case(title)
        if c is None:
            return None
        for name, data in files.items():
            c.path(name).write_bytes(data if isinstance(data, bytes) else data.encode())
        shutil.copyfile(h.store(backend), c.path("s.mkt"))
        res = c.mk("build", *([scene] if isinstance(scene, str) else scene), "-o", "s.mkt", "--backend", backend, "-q",
                   *extra, expect=expect, names=names or [scene if isinstance(scene, str) else scene[0]],
                   protect=list(files), prev=["s.mkt"], outputs=["s.mkt"], warn_ok=warn_ok,
                   label="build " + (scene if isinstance(scene, str) else " ".join(scene)))
        if res == "ok":
            scene_checks(h, c, "s.mkt", objs)
        return c

    cubes2 = [("a", (0, 0, 0), 1.0), ("b", (3, 0, 0), 1.0)]
    for backend in ("pagefile", "hdf5"):
        for bad in ("nan", "inf", "-inf", "1e39"):
            t = cube_obj(cubes2).replace("v 2.500000 -0.500000 -0.500000", "v 2.500000 %s -0.500000" % bad, 1)
            c = build_case("%s: OBJ vertex coordinate %s" % (backend, bad), {"n.obj": t}, "n.obj", "fail", backend)
            if c:
                h.finish_case(c)
        # NUL byte in a name (issue item 4): a store that opens, or a clean error
        tri = b"o a\0b\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
        c = build_case("%s: object name with a NUL byte" % backend, {"nul.obj": tri}, "nul.obj", "either", backend,
                       objs=[("a", [[0, 0, 0], [1, 1, 0]])])
        if c:
            h.finish_case(c)
        # 1 MiB name among 2000 objects (item 6)
        c = case("%s: a 1 MiB object name among 2000 tanker objects" % backend)
        if c:
            src = h.fix / "tanker2000.obj"
            if not src.exists():
                h.must("generate", "tanker", "--objects", "2000", "-o", src)
            text = src.read_text()
            i = text.index("\no ", len(text) // 2)
            j = text.index("\n", i + 1)
            text = text[:i] + "\no " + "n" * (1 << 20) + text[j:]
            c.path("big.obj").write_text(text)
            _, objs = ref_parse_obj(text)
            shutil.copyfile(h.store(backend), c.path("s.mkt"))
            res = c.mk("build", "big.obj", "-o", "s.mkt", "--backend", backend, "-q", expect="succeed",
                       names=["big.obj", "s.mkt"], protect=["big.obj"], prev=["s.mkt"], outputs=["s.mkt"],
                       label="build big.obj")
            c.note("build: %s in %.1f s (the harness limits a run to %d GiB of address space)" % (
                c.steps[-1][1].status(), c.steps[-1][1].secs, MEM_LIMIT >> 30))
            if res == "ok":
                c.note("store %d bytes" % c.path("s.mkt").stat().st_size)
                scene_checks(h, c, "s.mkt", objs)
            h.finish_case(c)

    # empty scenes
    empties = {"empty.obj": "", "verts.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "noface.obj": "o a\no b\n",
               "comments.obj": "# nothing\n\n", "empty.off": "OFF\n0 0 0\n",
               "empty.ply": "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
                            "property float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
               "empty.mks": ""}
    for name, data in empties.items():
        c = build_case("empty scene %s" % name, {name: data}, name, "fail")
        if c:
            h.finish_case(c)
    c = build_case("empty scene tanker:0", {}, "tanker:0", "fail", names=["tanker:0"])
    if c:
        h.finish_case(c)

    # deeply nested AC3D
    depth = 10000
    ac = ["AC3Db", 'MATERIAL "m" rgb 1 1 1  amb 1 1 1  emis 0 0 0  spec 0 0 0  shi 10  trans 0', "OBJECT world",
          "kids 1"]
    for i in range(depth):
        ac += ["OBJECT group", 'name "g%d"' % i, "kids 1"]
    ac += ["OBJECT poly", 'name "leaf"', "numvert 4", "0 0 0", "1 0 0", "0 1 0", "0 0 1", "numsurf 4"]
    for tri in ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)):
        ac += ["SURF 0x10", "mat 0", "refs 3"] + ["%d 0 0" % v for v in tri]
    ac += ["kids 0"]
    deep = "\n".join(ac) + "\n"
    c = build_case("AC3D nested %d levels (%d KB)" % (depth, len(deep) // 1024), {"deep.ac": deep}, "deep.ac", "either",
                   objs=[("leaf", [[0, 0, 0], [1, 1, 1]])])
    if c:
        h.finish_case(c)

    def ac3d(objs_):
        out = ["AC3Db", 'MATERIAL "m" rgb 1 1 1  amb 1 1 1  emis 0 0 0  spec 0 0 0  shi 10  trans 0', "OBJECT world",
               "kids %d" % len(objs_)]
        for name, numvert, verts, surfs in objs_:
            out += ["OBJECT poly", 'name "%s"' % name, "numvert %s" % numvert] + verts
            out += ["numsurf %s" % len(surfs)]
            for refs in surfs:
                out += ["SURF 0x10", "mat 0", "refs %s" % len(refs)] + ["%s 0 0" % v for v in refs]
            out += ["kids 0"]
        return "\n".join(out) + "\n"

    tet = ["0 0 0", "1 0 0", "0 1 0", "0 0 1"]
    good = ("good", 4, tet, [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
    other = ("other", 4, ["3 0 0", "4 0 0", "3 1 0", "3 0 1"], [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])
    bad_scenes = {
        "AC3D face index 9 of 4 vertices": ac3d([good, ("bad", 4, tet, [(0, 2, 9)])]),
        "AC3D face index -1": ac3d([good, ("bad", 4, tet, [(0, 2, -1)])]),
        "AC3D numvert -4": ac3d([other, ("bad", -4, tet, [(0, 1, 2)])]),
        "AC3D refs -3": ac3d([other, ("bad", 4, tet, [])]).replace(
            "numsurf 0", "numsurf 1\nSURF 0x10\nmat 0\nrefs -3\n0 0 0\n1 0 0\n2 0 0"),
        "AC3D numsurf -1": ac3d([other, ("bad", 4, tet, [])]).replace("numsurf 0", "numsurf -1"),
        "AC3D kids -1": ac3d([other]).replace("kids 1", "kids -1", 1),
        "AC3D numvert 2 with 4 vertex lines": ac3d([good, ("bad", 2, tet, [(0, 1, 2)])]),
    }
    for title, text in bad_scenes.items():
        c = build_case(title, {"bad.ac": text}, "bad.ac", "fail")
        if c:
            h.finish_case(c)
    off_tet = "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 %s\n"
    offs = {"OFF face index 7 of 4 vertices": off_tet % "7", "OFF face index -1": off_tet % "-1",
            "OFF vertex count -4": off_tet.replace("4 4 0", "-4 4 0") % "3",
            "OFF face count -4": off_tet.replace("4 4 0", "4 -4 0") % "3",
            "OFF face of 200 vertices on a line of 3": off_tet.replace("3 1 2 %s", "200 1 2 %s") % "3",
            "OFF counts larger than the file": off_tet.replace("4 4 0", "4000000 4000000 0") % "3"}
    for title, text in offs.items():
        c = build_case(title, {"bad.off": text}, "bad.off", "fail")
        if c:
            h.finish_case(c)
    ply = ("ply\nformat ascii 1.0\nelement vertex %s\nproperty float x\nproperty float y\nproperty float z\n"
           "element face %s\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
           "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 %s\n")
    plys = {"PLY face index 9 of 4 vertices": ply % (4, 4, 9), "PLY face index -1": ply % (4, 4, -1),
            "PLY vertex count -4": ply % (-4, 4, 3), "PLY face count -4": ply % (4, -4, 3),
            "PLY vertex count 2^40": ply % (1 << 40, 4, 3), "PLY face count past the data": ply % (4, 400, 3)}
    for title, text in plys.items():
        c = build_case(title, {"bad.ply": text}, "bad.ply", "fail")
        if c:
            h.finish_case(c)

    # truncated .mks
    mks = h.fix / "tanker200.mks"
    if not mks.exists():
        h.must("generate", "tanker", "--objects", "200", "-o", mks)
    data = mks.read_bytes()
    r = h.rng("scenes", "mks")
    cuts = sorted({len(data) - 1, 1, 7, 8, 16} | {r.randrange(16, len(data) - 1) for _ in range(5)})
    for cut in cuts:
        c = build_case("tanker200.mks truncated to %d of %d bytes" % (cut, len(data)), {"t.mks": data[:cut]}, "t.mks",
                       "fail")
        if c:
            c.note("t.mks: $MKTREE generate tanker --objects 200 -o t.mks; truncate -s %d t.mks" % cut)
            h.finish_case(c)

    # real-world coordinates: a 0.2 m cube at (500000, 5000000, 100), the brief's case, and one at a
    # position that is not a round number (fewer faces fall on float32 grid points by luck)
    for centre, full in (((500000.0, 5000000.0, 100.0), True), ((512345.678, 5412345.678, 101.234), False)):
        text = cube_obj([("utm_cube", centre, 0.2)], fmt="%.4f")
        where = "(%s)" % ", ".join("%.10g" % x for x in centre)
        pts = [("centre", list(centre), True)]
        for axis in range(3 if full else 2):
            for sgn in (-1, 1):
                for dist, inside in ((0.0999, True), (0.1001, False)):
                    p = list(centre)
                    p[axis] += sgn * dist
                    pts.append(("%s%s face %s" % ("-+"[sgn > 0], "xyz"[axis],
                                                  "0.1 mm inside" if inside else "0.1 mm outside"), p, inside))
        for backend in ("pagefile", "hdf5"):
            num += 1
            if not h.wanted("scenes", num):
                num += 2 * len(pts)
                continue
            c = h.new_case("scenes", num, "%s: 0.2 m cube at %s: build" % (backend, where))
            c.path("utm.obj").write_text(text)
            res = c.mk("build", "utm.obj", "-o", "utm.mkt", "--backend", backend, expect="succeed",
                       names=["utm.obj"], outputs=["utm.mkt"], label="build utm.obj")
            build_warned = warned(c.steps[-1][1].err)
            store_bytes = c.path("utm.mkt").read_bytes() if res == "ok" else None
            h.finish_case(c)
            for exact in (False, True):
                for label, p, inside in pts:
                    num += 1
                    if not h.wanted("scenes", num):
                        continue
                    mode = "exact" if exact else "AABB"
                    c = h.new_case("scenes", num, "%s: cube at %s, %s query at the %s" % (backend, where, mode, label))
                    c.path("utm.obj").write_text(text)
                    if store_bytes is None:
                        c.mk("build", "utm.obj", "-o", "utm.mkt", "--backend", backend, "-q", expect="succeed",
                             names=["utm.obj"], outputs=["utm.mkt"], label="build utm.obj")
                        h.finish_case(c)
                        continue
                    c.path("utm.mkt").write_bytes(store_bytes)
                    c.say("# utm.mkt: $MKTREE build utm.obj -o utm.mkt --backend %s" % backend)
                    want = [0] if inside else []

                    def check(pr, want=want, exact=exact, inside=inside, build_warned=build_warned):
                        try:
                            got = parse_answers(pr.out)[0][2]
                        except (ValueError, KeyError, IndexError) as e:
                            return "unparsable query output (%s)" % e
                        if got == want:
                            return None
                        if not exact and not inside and build_warned:
                            return None  # the build warned that boxes this far out are coarse: documented
                        return "hits %s, expected %s" % (got, want)
                    c.mk("query", "utm.mkt", "--point", "%.4f,%.4f,%.4f" % tuple(p), *(["--exact"] if exact else []),
                         expect="succeed", names=["utm.mkt"], check=check, label="query --point %s" % mode)
                    h.finish_case(c)

    # a real city tile in its real coordinates: every building's box centre must hit it (AABB)
    src = Path("/work/shared/data/city/denhaag_01.obj")
    if src.exists():
        first = src.open().readline()
        m = re.search(r"offset[^:]*:\s*([-\d.]+)\s+([-\d.]+)\s+([-\d.]+)", first)
        off = [float(x) for x in m.groups()] if m else [78248.66, 457604.591, 2.463]
        out = []
        for line in src.read_text().split("\n"):
            if line.startswith("v "):
                t = line.split()
                out.append("v %.4f %.4f %.4f" % tuple(float(t[i + 1]) + off[i] for i in range(3)))
            else:
                out.append(line)
        rd = "\n".join(out)
        _, objs = ref_parse_obj(rd)
        for backend in ("pagefile", "hdf5"):
            c = case("%s: denhaag_01.obj moved back to its RD coordinates (%.0f, %.0f): every box centre hits its "
                     "object" % (backend, off[0], off[1]))
            if c is None:
                continue
            c.path("rd.obj").write_text(rd)
            c.note("rd.obj: /work/shared/data/city/denhaag_01.obj with (%s) added to every vertex" %
                   ", ".join("%g" % x for x in off))
            res = c.mk("build", "rd.obj", "-o", "rd.mkt", "--backend", backend, "-q", expect="succeed",
                       names=["rd.obj"], outputs=["rd.mkt"], label="build rd.obj")
            if res == "ok":
                scene_checks(h, c, "rd.mkt", objs)
            h.finish_case(c)


# ---------------------------------------------------------------------------------------------------------
# 4. Arguments


def cat_args(h):
    num = 0
    store = h.store("pagefile")
    cubes = cube_obj(TINY_CUBES)

    def case(title, argv, expect="fail", names=(), files=None, setup=None, outputs=(), protect=(), check=None,
             allow_new=()):
        nonlocal num
        num += 1
        if not h.wanted("args", num):
            return
        c = h.new_case("args", num, title)
        c.path("s.mkt").write_bytes(store.read_bytes())
        c.path("c.obj").write_text(cubes)
        c.path("q.txt").write_text("point 1 1 1\nbox 0 0 0 5 5 5\n")
        c.path("d").mkdir()
        for name, data in (files or {}).items():
            c.path(name).write_text(data)
        if setup:
            setup(c)
        c.mk(*argv, expect=expect, names=list(names), protect=["s.mkt", "c.obj", "q.txt"] + list(protect),
             outputs=outputs, check=check, allow_new=allow_new, label=" ".join(str(a) for a in argv)[:70])
        h.finish_case(c)

    def fifo(name):
        def f(c):
            os.mkfifo(c.path(name))
            c.say("mkfifo %s" % name)
        return f

    def link(name, target):
        def f(c):
            os.symlink(target, c.path(name))
            c.say("ln -s %s %s" % (target, name))
        return f

    bad_ints = ["-1", "99999999999999999999999", "abc", "", "1.5", "--", "0x"]
    # generate tanker
    for v in bad_ints + ["0", "4294967297"]:
        case("generate tanker --objects %r" % v, ["generate", "tanker", "--objects", v, "-o", "g.obj"],
             names=["--objects", "objects", v or "''"], outputs=["g.obj"])
    for v in ["-1", "99999999999999999999999", "abc", "", "1.5"]:
        case("generate tanker --seed %r" % v, ["generate", "tanker", "--objects", "5", "--seed", v, "-o", "g.obj"],
             names=["--seed", "seed"], outputs=["g.obj"])
    for out in ["g.txt", "d", "d/", "missing/g.obj"]:
        case("generate tanker -o %s" % out, ["generate", "tanker", "--objects", "5", "-o", out],
             names=[out.rstrip("/")])
    # generate queries
    for v in bad_ints + ["0"]:
        case("generate queries --count %r" % v, ["generate", "queries", "s.mkt", "-o", "g.q", "--count", v],
             names=["--count", "count"])
    for v in ["-1", "99999999999999999999999", "abc"]:
        case("generate queries --seed %r" % v, ["generate", "queries", "s.mkt", "-o", "g.q", "--seed", v],
             names=["--seed", "seed"])
    for v in ["", "0", "-1", "abc", "1,,2", "nan", "inf", "1e400", "1,"]:
        case("generate queries --sides %r" % v, ["generate", "queries", "s.mkt", "-o", "g.q", "--sides", v],
             names=["--sides", "sides"])
    case("generate queries on a missing store", ["generate", "queries", "nope.mkt", "-o", "g.q"], names=["nope.mkt"])
    case("generate queries on a directory", ["generate", "queries", "d", "-o", "g.q"], names=["d"])
    case("generate queries -o a directory", ["generate", "queries", "s.mkt", "-o", "d"], names=["d"])
    # build options
    opts = {"--zstd-level": ["abc", "", "99999999999999999999", "1000", "-1000000", "23"],
            "--block-size": ["-1", "0", "100", "511", "4294967296", "abc", ""],
            "--blocks-per-page": ["-1", "0", "4294967295", "300000", "abc"],
            "--r": ["-0.1", "0.5", "nan", "inf", "abc", "", "1e400"],
            "--split-budget": ["-1", "99999999999999999999", "abc", ""],
            "--backend": ["", "sqlite"], "--codec": ["", "lz4"], "--split-policy": ["", "x"]}
    for opt, vals in opts.items():
        for v in vals:
            case("build %s %r" % (opt, v), ["build", "tanker:50", "-o", "b.mkt", opt, v, "-q"],
                 names=[opt, opt.lstrip("-"), opt.lstrip("-").replace("-", " ")], outputs=["b.mkt"])
    for spec in ["tanker:10:abc", "tanker:-1", "tanker:0", "tanker:abc", "tanker:", "tanker:10:", "tanker:10:1:2",
                 "tanker:99999999999999999999", "tanker:10:-1", "tanker: 10", "tanker:1e3",
                 "tanker:10:99999999999999999999"]:
        case("build %s" % spec, ["build", spec, "-o", "b.mkt", "-q"], names=[spec], outputs=["b.mkt"])
    case("build c.obj -o c.obj (the input must survive)", ["build", "c.obj", "-o", "c.obj", "-q"], names=["c.obj"])
    for out in ["d", "d/", "missing/b.mkt", "."]:
        case("build -o %s" % out, ["build", "c.obj", "-o", out, "-q"], names=[out.rstrip("/") or out])
    case("build a FIFO", ["build", "f.obj", "-o", "b.mkt", "-q"], names=["f.obj"], setup=fifo("f.obj"))
    case("build a directory named x.obj", ["build", "x.obj", "-o", "b.mkt", "-q"], names=["x.obj"],
         setup=lambda c: c.path("x.obj").mkdir())
    case("build /dev/zero as z.obj", ["build", "z.obj", "-o", "b.mkt", "-q"], names=["z.obj"],
         setup=link("z.obj", "/dev/zero"))
    case("build /dev/urandom as u.obj", ["build", "u.obj", "-o", "b.mkt", "-q"], names=["u.obj"],
         setup=link("u.obj", "/dev/urandom"))
    case("build /dev/null as n.obj", ["build", "n.obj", "-o", "b.mkt", "-q"], names=["n.obj"],
         setup=link("n.obj", "/dev/null"))
    case("build a missing file", ["build", "nope.obj", "-o", "b.mkt", "-q"], names=["nope.obj"])
    case("build a store as a scene", ["build", "s.mkt", "-o", "b.mkt", "-q"], names=["s.mkt"])
    case("build a file of unknown type", ["build", "q.txt", "-o", "b.mkt", "-q"], names=["q.txt"])
    case("build without -o", ["build", "c.obj", "-q"], names=["-o", "output", "--output", "required"])
    # info
    case("info a FIFO", ["info", "f.mkt"], names=["f.mkt"], setup=fifo("f.mkt"))
    case("info a directory", ["info", "d"], names=["d"])
    case("info /dev/null", ["info", "n.mkt"], names=["n.mkt"], setup=link("n.mkt", "/dev/null"))
    case("info /dev/zero", ["info", "z.mkt"], names=["z.mkt"], setup=link("z.mkt", "/dev/zero"))
    case("info an OBJ file", ["info", "c.obj"], names=["c.obj"])
    case("info an empty file", ["info", "e.mkt"], names=["e.mkt"], files={"e.mkt": ""})
    case("info a missing file", ["info", "nope.mkt"], names=["nope.mkt"])
    # query
    for v in ["", "1,2", "1,2,3,4", "nan,0,0", "inf,0,0", "a,b,c", "1e400,0,0", "1,,2", "1;2;3"]:
        case("query --point %r" % v, ["query", "s.mkt", "--point", v], names=["--point", "point"])
    for v in ["", "1,1,1,0,0,0", "0,0,0,1,1", "nan,0,0,1,1,1", "0,0,0,1,1,inf"]:
        case("query --box %r" % v, ["query", "s.mkt", "--box", v], names=["--box", "box"])
    for v in ["-1", "99999999999999999999", "abc", ""]:
        case("query --cache-pages %r" % v, ["query", "s.mkt", "--point", "1,1,1", "--cache-pages", v],
             names=["--cache-pages", "cache-pages"])
    case("query --queries a FIFO", ["query", "s.mkt", "--queries", "f.q"], names=["f.q"], setup=fifo("f.q"))
    case("query --queries a directory", ["query", "s.mkt", "--queries", "d"], names=["d"])
    case("query --queries /dev/zero", ["query", "s.mkt", "--queries", "z.q"], names=["z.q"],
         setup=link("z.q", "/dev/zero"))
    case("query --queries a missing file", ["query", "s.mkt", "--queries", "nope.q"], names=["nope.q"])
    for title, text in {"a NaN point": "point nan 0 0\n", "a box with 5 numbers": "box 0 0 0 1 1\n",
                        "an inverted box": "box 1 1 1 0 0 0\n", "an unknown kind": "sphere 0 0 0 1\n",
                        "a 1 MB line": "point " + "1" * 1000000 + " 0 0\n", "a NUL byte": "point 0\0 0 0\n",
                        "a point of 1e400": "point 1e400 0 0\n"}.items():
        case("query --queries with %s" % title, ["query", "s.mkt", "--queries", "b.q"], names=["b.q"],
             files={"b.q": text})
    case("query with no query", ["query", "s.mkt"], names=["--point", "--box", "--queries", "query"])
    case("query a FIFO store", ["query", "f.mkt", "--point", "1,1,1"], names=["f.mkt"], setup=fifo("f.mkt"))
    case("query an empty queries file", ["query", "s.mkt", "--queries", "e.q"], expect="either", names=["e.q"],
         files={"e.q": "# nothing\n"})
    # export and render
    for v in ["-1", "abc", "", "99999999999999999999"]:
        case("export --level %r" % v, ["export", "s.mkt", "--level", v, "-o", "x.ply", "-q"],
             names=["--level", "level"])
        case("render --level %r" % v, ["render", "s.mkt", "--level", v, "-o", "x.png", "-q"],
             names=["--level", "level"])
    for out in ["x.txt", "d", "d/", "missing/x.ply"]:
        case("export -o %s" % out, ["export", "s.mkt", "--level", "1", "-o", out, "-q"], names=[out.rstrip("/")])
    for v in ["0x0", "63x64", "16385x64", "abc", "-1x-1", "100x", "x100", "100x100x1", "", "99999999999999999999x64"]:
        case("render --size %r" % v, ["render", "s.mkt", "--level", "1", "--size", v, "-o", "x.png", "-q"],
             names=["--size", "size"])
    case("render --view diagonal", ["render", "s.mkt", "--level", "1", "--view", "diagonal", "-o", "x.png", "-q"],
         names=["--view", "view", "diagonal"])
    for out in ["x.jpg", "d", "missing/x.png"]:
        case("render -o %s" % out, ["render", "s.mkt", "--level", "1", "-o", out, "-q"], names=[out])


# ---------------------------------------------------------------------------------------------------------
# 5. Full disk


def mount_tmpfs(h, d, size):
    d.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=%d" % size, "tmpfs", str(d)], capture_output=True,
                       text=True)
    if r.returncode != 0:
        return r.stderr.strip() or "mount failed"
    h.mounts.append(d)
    return None


def umount(h, d):
    subprocess.run(["umount", str(d)], capture_output=True)
    if d in h.mounts:
        h.mounts.remove(d)


def cat_disk(h):
    probe = h.work / "mount-probe"
    err = mount_tmpfs(h, probe, 1 << 20)
    if err:
        h.skipped.append(("disk", "mount refused (%s)" % err))
        return
    umount(h, probe)
    probe.rmdir()
    num = 0
    new_scene = "tanker:38400:2"
    for backend in ("hdf5", "pagefile"):
        prev = h.store(backend)
        big = h.store(backend, new_scene)
        qfile = h.queries_for(h.store("pagefile"), "tanker3000.q")
        qbig = h.queries_for(h.store("pagefile", new_scene), "tanker38400.q")
        want_prev = h.answers(prev, qfile)
        want_new = h.answers(big, qbig)
        prev_size, new_size = prev.stat().st_size, big.stat().st_size
        # the spill files sit next to the store: a build needs about store + spill at its peak
        fracs = [0.02, 0.15, 0.35, 0.6, 0.85, 0.95, 1.0, 1.1, 1.3, 1.5, 1.7, 1.85, 1.95, 2.1]
        plans = [(f, prev_size + int(f * new_size)) for f in fracs]
        # The last phases (metadata, flush and close) fail only within a few hundred KiB of the smallest disk
        # that fits: find that size by bisection (32 KiB steps), then fail just below it.
        fit = smallest_fit(h, backend, prev, new_scene, prev_size, prev_size + 3 * new_size)
        if fit is None:
            h.setup_notes.append("full disk, %s: %s did not fit in %d bytes; the near-fit cases are left out"
                                 % (backend, new_scene, prev_size + 3 * new_size))
        for d in (32, 64, 96, 128, 192, 256, 384, 512):
            plans.append(("fine", (fit or prev_size + 2 * new_size) - (d << 10)))
        plans.append(("issue", 20 << 20))
        for f, size in plans:
            num += 1
            if not h.wanted("disk", num):
                continue
            size = (size + 4095) // 4096 * 4096
            with_prev = f != "issue"
            c = h.new_case("disk", num, "%s: build %s on a %d KiB tmpfs%s%s" % (
                backend, new_scene, size >> 10, " holding the previous store" if with_prev else " (issue 18 item 3)",
                " (%d KiB below the smallest that fits)" % ((fit - size) >> 10) if f == "fine" and fit else ""))
            disk = c.dir / "disk"
            shutil.copyfile(qfile, c.path("small.q"))
            shutil.copyfile(qbig, c.path("big.q"))
            if with_prev:
                c.path("prev.mkt").write_bytes(prev.read_bytes())
            c.save_inputs()
            err = mount_tmpfs(h, disk, size)
            if err:
                c.note("mount failed: " + err)
                h.finish_case(c)
                continue
            try:
                c.say("mkdir -p disk && mount -t tmpfs -o size=%d tmpfs disk" % size)
                if with_prev:
                    shutil.copyfile(c.path("prev.mkt"), disk / "s.mkt")
                    c.say("cp prev.mkt disk/s.mkt")
                c.mk("build", new_scene, "-o", "disk/s.mkt", "--backend", backend, "-q", expect="either",
                     names=["s.mkt"], prev=["disk/s.mkt"] if with_prev else [], outputs=["disk/s.mkt"],
                     label="build on a full disk")
                first = c.steps[-1]
                if first[1].exited and first[1].rc == 0:
                    c.note("the build fitted in %d KiB" % (size >> 10))
                    c.mk("query", "disk/s.mkt", "--queries", "big.q", expect="succeed", names=["s.mkt"],
                               check=lambda p: _diff(p, want_new), label="query the new store")
                elif with_prev and not c.stopped():
                    c.mk("query", "disk/s.mkt", "--queries", "small.q", expect="succeed", names=["s.mkt"],
                         check=lambda p: _diff(p, want_prev), label="query the previous store")
                # then with enough space, at the same path, over whatever was left
                subprocess.run(["mount", "-o", "remount,size=%d" % (256 << 20), str(disk)], check=True)
                c.say("mount -o remount,size=%d disk" % (256 << 20))
                if not c.stopped():
                    c.mk("build", new_scene, "-o", "disk/s.mkt", "--backend", backend, "-q", expect="succeed",
                         names=["s.mkt"], outputs=["disk/s.mkt"], allow_new=["disk/s.mkt.tmp.*", "disk/s.mkt.lock"],
                         label="build again with space")
                    if c.steps[-1][2] == "ok":
                        c.mk("query", "disk/s.mkt", "--queries", "big.q", expect="succeed", names=["s.mkt"],
                             check=lambda p: _diff(p, want_new), label="query the rebuilt store")
                left = sorted(n for n in os.listdir(disk) if n != "s.mkt")
                if left:
                    c.note("left in the folder at the end: " + ", ".join(left))
                    c.record("leftovers", c.steps[-1][1], "unclean", "left " + ", ".join(left[:4]))
                c.say("umount disk")
            finally:
                umount(h, disk)
            h.finish_case(c)


def smallest_fit(h, backend, prev, scene, lo, hi):
    """The smallest tmpfs size (32 KiB steps) holding prev in which `build scene` over it succeeds."""
    d = h.work / "fit-probe"

    def fits(size):
        size = (size + 4095) // 4096 * 4096
        if mount_tmpfs(h, d, size):
            return False
        try:
            shutil.copyfile(prev, d / "s.mkt")
            p = run([str(h.mktree), "build", scene, "-o", str(d / "s.mkt"), "--backend", backend, "-q"], h.work,
                    3 * h.timeout)
            return p.rc == 0
        finally:
            umount(h, d)

    if not fits(hi):
        return None
    while hi - lo > (32 << 10):
        mid = (lo + hi) // 2
        if fits(mid):
            hi = mid
        else:
            lo = mid
    return hi


def _diff(p, want):
    try:
        return diff_answers(parse_answers(p.out), want)
    except (ValueError, KeyError) as e:
        return "unparsable query output (%s)" % e


# ---------------------------------------------------------------------------------------------------------
# 6. Kills


def cat_kills(h):
    num = 0
    new_scene = "tanker:38400:2"
    for backend in ("hdf5", "pagefile"):
        prev = h.store(backend)
        big = h.store(backend, new_scene)
        qfile = h.queries_for(h.store("pagefile"), "tanker3000.q")
        qbig = h.queries_for(h.store("pagefile", new_scene), "tanker38400.q")
        want_prev = h.answers(prev, qfile)
        want_new = h.answers(big, qbig)
        # how long a build takes here, for the kill times
        t0 = time.monotonic()
        tmpd = h.work / "kill-timing"
        tmpd.mkdir(exist_ok=True)
        run([str(h.mktree), "build", new_scene, "-o", str(tmpd / "t.mkt"), "--backend", backend, "-q"], tmpd, 120)
        dur = time.monotonic() - t0
        shutil.rmtree(tmpd)
        for k in range(10):
            num += 1
            if not h.wanted("kills", num):
                continue
            r = h.rng("kills", backend, k)
            at = r.uniform(0.02, dur * 0.95)
            c = h.new_case("kills", num, "%s: kill -9 at %.2f s of a %.2f s build over a good store" % (
                backend, at, dur))
            c.path("s.mkt").write_bytes(prev.read_bytes())
            shutil.copyfile(qfile, c.path("small.q"))
            shutil.copyfile(qbig, c.path("big.q"))
            c.save_inputs()
            argv = [str(h.mktree), "build", new_scene, "-o", "s.mkt", "--backend", backend, "-q"]
            c.say("$MKTREE %s & sleep %.2f; kill -9 $!" % (shlex.join(argv[1:]), at))
            p = spawn(argv, c.dir)
            time.sleep(at)
            try:
                os.killpg(p.popen.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            finish(p, h.timeout)
            killed = p.sig == signal.SIGKILL
            c.note("the build %s" % ("was killed" if killed else "had ended: " + p.status()))
            if p.exited and p.rc != 0:
                c.record("build (killed)", p, "unclean", "the build failed before the kill: " + p.err.strip()[-200:])
            elif p.sig not in (None, signal.SIGKILL):
                c.record("build (killed)", p, "crash", "killed by " + signal.Signals(p.sig).name)
            # the store at the path: the old one (or the new one if the build had committed)
            same = c.path("s.mkt").exists() and sha(c.path("s.mkt")) == sha(c.keep / "s.mkt")
            if not c.path("s.mkt").exists():
                c.record("after the kill", p, "unclean", "s.mkt is gone")
            elif same:
                c.mk("query", "s.mkt", "--queries", "small.q", expect="succeed", names=["s.mkt"],
                     check=lambda pr: _diff(pr, want_prev), label="query the old store")
            else:
                c.note("s.mkt was replaced (the build had committed)")
                c.mk("query", "s.mkt", "--queries", "big.q", expect="succeed", names=["s.mkt"],
                     check=lambda pr: _diff(pr, want_new), label="query the new store")
            inputs = {"s.mkt", "small.q", "big.q"}
            left = sorted(n for n in os.listdir(c.dir) if n not in inputs)
            if left:
                c.note("left by the killed build: " + ", ".join(left))
            if not c.stopped():
                c.mk("build", "tanker:3000", "-o", "s.mkt", "--backend", backend, "-q", expect="succeed",
                     names=["s.mkt"], outputs=["s.mkt"], allow_new=["s.mkt.tmp.*", "s.mkt.lock"],
                     label="the next build")
                if c.steps[-1][2] == "ok":
                    c.mk("query", "s.mkt", "--queries", "small.q", expect="succeed", names=["s.mkt"],
                         check=lambda pr: _diff(pr, want_prev), label="query after the next build")
            left2 = sorted(n for n in os.listdir(c.dir) if n not in inputs)
            if left2:
                c.note("left after the next build: " + ", ".join(left2))
            h.finish_case(c)


# ---------------------------------------------------------------------------------------------------------
# 7. Concurrency


def cat_concurrency(h):
    num = 0
    sa, sb = "tanker:38400:1", "tanker:38400:2"
    for backend in ("hdf5", "pagefile"):
        qbig = h.queries_for(h.store("pagefile", sb), "tanker38400.q")
        want = {sa: h.answers(h.store(backend, sa), qbig), sb: h.answers(h.store(backend, sb), qbig)}
        t0 = time.monotonic()
        tmpd = h.work / "conc-timing"
        tmpd.mkdir(exist_ok=True)
        run([str(h.mktree), "build", sa, "-o", str(tmpd / "t.mkt"), "--backend", backend, "-q"], tmpd, 120)
        dur = time.monotonic() - t0
        shutil.rmtree(tmpd)
        # 7a. two overlapping builds of one path. docs/cli.md: "a concurrent build of the same path fails".
        for k in range(6):
            num += 1
            if not h.wanted("concurrency", num):
                continue
            r = h.rng("conc", backend, k)
            d = r.uniform(0.0, dur * 0.8)
            with_prev = k % 2 == 0
            c = h.new_case("concurrency", num, "%s: second build of the same store %.2f s into a %.2f s build%s" % (
                backend, d, dur, ", previous store present" if with_prev else ""))
            if with_prev:
                c.path("s.mkt").write_bytes(h.store(backend).read_bytes())
            shutil.copyfile(qbig, c.path("big.q"))
            c.save_inputs()
            a = [str(h.mktree), "build", sa, "-o", "s.mkt", "--backend", backend, "-q"]
            b = [str(h.mktree), "build", sb, "-o", "s.mkt", "--backend", backend, "-q"]
            c.say("$MKTREE %s & sleep %.2f; $MKTREE %s; wait" % (shlex.join(a[1:]), d, shlex.join(b[1:])))
            pa = spawn(a, c.dir)
            # Watch the first build while waiting: one that ends before the second starts does not overlap it.
            pa_end, start_b = None, time.monotonic() + d
            while time.monotonic() < start_b:
                if pa_end is None and pa.popen.poll() is not None:
                    pa_end = time.monotonic()
                time.sleep(0.002)
            pb = spawn(b, c.dir)
            wait_all([pa, pb], 3 * h.timeout)
            if pa_end is not None:
                pa.t1 = pa_end
            overlap = pb.t0 < pa.t1
            outcome, why = None, ""
            for label, p in (("first build", pa), ("second build", pb)):
                if p.timed_out:
                    outcome, why = "hang", label + " timed out"
                elif p.sig is not None:
                    outcome, why = "crash", label + " killed by " + signal.Signals(p.sig).name
            oks = [s for s, p in ((sa, pa), (sb, pb)) if p.rc == 0]
            if outcome is None:
                fails = [p for p in (pa, pb) if p.rc not in (0, None)]
                if len(oks) == 2 and overlap:
                    outcome, why = "wrong", "both overlapping builds exited 0 (docs/cli.md: the second fails)"
                elif len(oks) == 2:
                    outcome, why = "ok", "no overlap"
                elif not oks:
                    outcome, why = "unclean", "both builds failed: " + " / ".join(p.err.strip()[-120:] for p in fails)
                else:
                    e = error_line_problem(fails[0].err, ["s.mkt"])
                    outcome, why = ("unclean", "the refused build: " + e) if e else ("clean", "")
            c.record("two builds", pb if pb.rc != 0 else pa, outcome, why)
            c.note("first build: %s; second build: %s; overlap %s" % (pa.status(), pb.status(), overlap))
            if not c.stopped() and oks:
                # the store must be the successful build's (the last to commit if both did)
                winner = oks[-1] if len(oks) == 1 else (sb if pb.t1 > pa.t1 else sa)
                def check(p, winner=winner):
                    got = parse_answers(p.out)
                    if diff_answers(got, want[winner]) is None:
                        return None
                    other = sa if winner == sb else sb
                    if diff_answers(got, want[other]) is None:
                        return "the store holds %s's answers, but %s is the build that succeeded last" % (other, winner)
                    return "the store matches neither build: " + diff_answers(got, want[winner])
                c.mk("query", "s.mkt", "--queries", "big.q", expect="succeed", names=["s.mkt"], check=check,
                     label="query the result")
            left = sorted(n for n in os.listdir(c.dir) if n not in ("s.mkt", "big.q"))
            if left:
                c.record("leftovers", pa, "unclean", "left " + ", ".join(left[:4]))
            h.finish_case(c)
        # 7b. readers while the store is rebuilt: every answer is the old store's or the new one's
        for k in range(5):
            num += 1
            if not h.wanted("concurrency", num):
                continue
            c = h.new_case("concurrency", num, "%s: readers during rebuild %d (alternating %s / %s)" % (
                backend, k, sa, sb))
            old, new = (sa, sb) if k % 2 == 0 else (sb, sa)
            c.path("s.mkt").write_bytes(h.store(backend, old).read_bytes())
            shutil.copyfile(qbig, c.path("big.q"))
            c.save_inputs()
            b = [str(h.mktree), "build", new, "-o", "s.mkt", "--backend", backend, "-q"]
            rq = [str(h.mktree), "query", "s.mkt", "--queries", "big.q", "--cold"]
            c.say("$MKTREE %s &  # while it runs:" % shlex.join(b[1:]))
            c.say("while kill -0 $! 2>/dev/null; do $MKTREE %s; done" % shlex.join(rq[1:]))
            pb = spawn(b, c.dir)
            runs, bad = 0, None
            seen = set()
            while True:
                done = pb.popen.poll() is not None
                p = run(rq, c.dir, h.timeout)
                runs += 1
                if not p.exited or p.rc != 0:
                    bad = ("hang" if p.timed_out else "crash" if p.sig else "unclean",
                           "a reader: %s: %s" % (p.status(), p.err.strip()[-200:]), p)
                    break
                got = parse_answers(p.out)
                if diff_answers(got, want[old]) is None:
                    seen.add("old")
                elif diff_answers(got, want[new]) is None:
                    seen.add("new")
                else:
                    bad = ("wrong", "a reader got neither store's answers: " + diff_answers(got, want[new]), p)
                    break
                if done:
                    break
            finish(pb, h.timeout)
            c.note("%d reader runs; answers seen: %s; build %s" % (runs, ", ".join(sorted(seen)), pb.status()))
            if bad:
                c.record("readers", bad[2], bad[0], bad[1])
            if not pb.exited or pb.rc != 0:
                c.record("rebuild", pb, "crash" if pb.sig else "hang" if pb.timed_out else "unclean",
                         "the rebuild: " + pb.status() + " " + pb.err.strip()[-200:])
            else:
                c.record("readers", pb, "ok", "")
            h.finish_case(c)
        # 7c. readers while the store is replaced many times: the commit step of a build (rename over the path)
        # repeated every 5 ms with hard links of the two stores, so that renames land inside readers' opens
        for k in range(2):
            num += 1
            if not h.wanted("concurrency", num):
                continue
            c = h.new_case("concurrency", num, "%s: 40 readers while the store is replaced by rename every 5 ms (%d)"
                           % (backend, k))
            shutil.copyfile(h.store(backend, sa), c.path("a.mkt"))
            shutil.copyfile(h.store(backend, sb), c.path("b.mkt"))
            shutil.copyfile(c.path("a.mkt"), c.path("s.mkt"))
            shutil.copyfile(qbig, c.path("big.q"))
            c.save_inputs()
            rq = [str(h.mktree), "query", "s.mkt", "--queries", "big.q", "--cold"]
            c.say("(i=0; while :; do ln -f $([ $((i%2)) = 0 ] && echo a.mkt || echo b.mkt) n.mkt && mv n.mkt s.mkt; "
                  "i=$((i+1)); sleep 0.005; done) &")
            c.say("for i in $(seq 40); do $MKTREE %s | md5sum; done; kill %%1  # two distinct sums expected" %
                  shlex.join(rq[1:]))
            stop = []

            def renamer(d=c.dir):
                i = 0
                while not stop:
                    tmp = d / "n.mkt"
                    if tmp.exists():
                        tmp.unlink()
                    os.link(d / ("a.mkt" if i % 2 else "b.mkt"), tmp)
                    os.rename(tmp, d / "s.mkt")
                    i += 1
                    time.sleep(0.005)
            t = threading.Thread(target=renamer)
            t.start()
            bad, seen, runs = None, set(), 0
            try:
                for _ in range(40):
                    p = run(rq, c.dir, h.timeout)
                    runs += 1
                    if not p.exited or p.rc != 0:
                        bad = ("hang" if p.timed_out else "crash" if p.sig else "unclean",
                               "reader %d: %s: %s" % (runs, p.status(), p.err.strip()[-200:]), p)
                        break
                    got = parse_answers(p.out)
                    if diff_answers(got, want[sa]) is None:
                        seen.add(sa)
                    elif diff_answers(got, want[sb]) is None:
                        seen.add(sb)
                    else:
                        bad = ("wrong", "reader %d got neither store's answers: %s" % (
                            runs, diff_answers(got, want[sa])), p)
                        break
            finally:
                stop.append(1)
                t.join()
            c.note("%d reader runs; answers seen: %s" % (runs, ", ".join(sorted(seen))))
            if bad:
                c.record("readers", bad[2], bad[0], bad[1])
            else:
                c.record("readers", p, "ok", "")
            h.finish_case(c)



# ---------------------------------------------------------------------------------------------------------
# 8. Sharded stores (docs/shards.md): a manifest, its shard stores and their id files


def cat_shards(h):
    """Damaged, swapped, foreign and missing files of a sharded store (`build --shards 3`), through info,
    query, a batch count (two threads) and clash (when the pristine manifest's clash succeeds). A truncated,
    swapped, foreign or missing file must give an error; a flipped byte an error or the right answers. Errors
    must be one line naming the file (any of the files the case changed)."""
    num = 0
    K = 3
    for backend in ("pagefile", "hdf5"):
        fix = h.fix / ("shards_%s" % backend)
        other = h.fix / ("shards_%s_other" % backend)      # the same scene, built again: another build id
        scene2 = h.fix / ("shards_%s_scene2" % backend)    # another scene
        for d, scene in ((fix, "tanker:3000"), (other, "tanker:3000"), (scene2, "tanker:3000:2")):
            if not (d / "s.mkt").exists():
                d.mkdir(parents=True, exist_ok=True)
                h.must("build", scene, "-o", "s.mkt", "--backend", backend, "--shards", K, "-q", cwd=d)
        files = sorted(f.name for f in fix.iterdir())
        qfile = h.queries_for(h.store("pagefile"), "tanker3000.q")
        want = h.answers(fix / "s.mkt", qfile)
        want_exact = h.answers(fix / "s.mkt", qfile, exact=True)
        pc = h.tool(*CLASH_ARGS(fix / "s.mkt"), cwd=fix)
        clash_want = pc.out if pc.rc == 0 else None
        if clash_want is None:
            h.setup_notes.append("shards %s: no clash step, clash on the pristine manifest fails (%s)" %
                                 (backend, pc.err.strip()[:120]))

        def store(i):
            return "s.mkt.shard-%d.mkt" % i

        def ids(i):
            return "s.mkt.shard-%d.ids" % i

        cases = []  # (title, edit(case dir, rng) -> names the error may give, must fail)
        targets = [("s.mkt", 12, 6), (store(0), 12, 4), (store(2), 6, 3), (ids(1), 10, 4)]
        for name, flips, truncs in targets:
            size = (fix / name).stat().st_size
            for k in range(flips):
                r = h.rng("shards", backend, name, "flip", k)
                pos = r.randrange(min(size, 4096)) if k % 2 == 0 else r.randrange(size)
                x = r.randrange(1, 256)

                def edit(d, name=name, pos=pos, x=x):
                    b = bytearray((d / name).read_bytes())
                    b[pos] ^= x
                    (d / name).write_bytes(bytes(b))
                cases.append(("%s: byte %d of %s xor 0x%02x" % (backend, pos, name, x), edit, [name], False))
            for k in range(truncs):
                r = h.rng("shards", backend, name, "trunc", k)
                pos = r.randrange(size) if k else 0

                def edit(d, name=name, pos=pos):
                    with open(d / name, "r+b") as f:
                        f.truncate(pos)
                cases.append(("%s: %s truncated to %d of %d bytes" % (backend, name, pos, size), edit, [name], True))

        def swap(a, b):
            def edit(d):
                ta, tb = (d / a).read_bytes(), (d / b).read_bytes()
                (d / a).write_bytes(tb)
                (d / b).write_bytes(ta)
            return edit
        cases.append(("%s: shard stores 0 and 1 swapped" % backend, swap(store(0), store(1)), [store(0), store(1)],
                      True))
        cases.append(("%s: id files 0 and 1 swapped" % backend, swap(ids(0), ids(1)), [ids(0), ids(1)], True))

        def swap_shards(d):
            swap(store(0), store(1))(d)
            swap(ids(0), ids(1))(d)
        cases.append(("%s: shards 0 and 1 (store and id file) swapped" % backend, swap_shards,
                      [store(0), store(1), ids(0), ids(1)], True))

        def copy_from(src, names_):
            def edit(d):
                for n in names_:
                    shutil.copyfile(src / n, d / n)
            return edit
        cases.append(("%s: the manifest of another build of the same scene" % backend, copy_from(other, ["s.mkt"]),
                      ["s.mkt"] + [store(i) for i in range(K)] + [ids(i) for i in range(K)], True))
        cases.append(("%s: the manifest of another scene" % backend, copy_from(scene2, ["s.mkt"]),
                      ["s.mkt"] + [store(i) for i in range(K)] + [ids(i) for i in range(K)], True))
        cases.append(("%s: shard 1 (store and id file) from another build of the same scene" % backend,
                      copy_from(other, [store(1), ids(1)]), [store(1), ids(1)], True))
        cases.append(("%s: shard 1's store from another build of the same scene" % backend,
                      copy_from(other, [store(1)]), [store(1)], True))
        cases.append(("%s: shard 1's id file from another build of the same scene" % backend,
                      copy_from(other, [ids(1)]), [ids(1)], True))
        cases.append(("%s: shard 2 (store and id file) from another scene" % backend,
                      copy_from(scene2, [store(2), ids(2)]), [store(2), ids(2)], True))

        def remove(n):
            def edit(d):
                (d / n).unlink()
            return edit
        cases.append(("%s: shard 1's store missing" % backend, remove(store(1)), [store(1)], True))
        cases.append(("%s: shard 2's id file missing" % backend, remove(ids(2)), [ids(2)], True))

        def plain_store(d):
            (d / store(0)).unlink()
            (d / store(0)).mkdir()
        cases.append(("%s: shard 0's store a directory" % backend, plain_store, [store(0)], True))

        for title, edit, names, must_fail in cases:
            num += 1
            if not h.wanted("shards", num):
                continue
            c = h.new_case("shards", num, title)
            for f in files:
                shutil.copyfile(fix / f, c.path(f))
            edit(c.dir)
            changed = [f for f in files if not (c.dir / f).is_file() or
                       (c.dir / f).read_bytes() != (fix / f).read_bytes()]
            if not changed:  # e.g. another build's shard store: byte for byte the same file
                c.note("every file is byte-identical to the pristine one's: the right answers are expected")
            shutil.copyfile(qfile, c.path("q.txt"))
            c.note("made by scripts/hostile.py (shards): $MKTREE build tanker:3000 -o s.mkt --backend %s --shards %d -q"
                   "; then: %s" % (backend, K, title))
            protect = [f for f in files if (c.dir / f).is_file()]

            def q_check(w):
                def f(p):
                    try:
                        return diff_answers(parse_answers(p.out), w)
                    except (ValueError, KeyError) as e:
                        return "unparsable query output (%s)" % e
                return f

            def count_check(p, w=want):
                try:
                    got = [json.loads(x)["hit_count"] for x in p.out.splitlines() if x.strip()]
                except (ValueError, KeyError) as e:
                    return "unparsable query output (%s)" % e
                exp = [len(x[2]) for x in w]
                return None if got == exp else "counts differ: %s..., expected %s..." % (got[:6], exp[:6])

            c.mk("info", "s.mkt", names=names, protect=protect, label="info")
            if not c.stopped():
                c.mk("query", "s.mkt", "--queries", "q.txt", names=names, check=q_check(want), protect=protect,
                     label="query")
            if not c.stopped():
                c.mk("query", "s.mkt", "--queries", "q.txt", "--exact", names=names, check=q_check(want_exact),
                     protect=protect, label="query --exact")
            if not c.stopped():
                c.mk("query", "s.mkt", "--queries", "q.txt", "--count", "--threads", 2, names=names, check=count_check,
                     protect=protect, label="query --count --threads 2 (batch)")
            if clash_want is not None and not c.stopped():  # once clash reads manifests
                c.mk(*CLASH_ARGS("s.mkt"), names=names, check=clash_check(clash_want), protect=protect,
                     label="clash")
            h.finish_case(c, require_error=must_fail and bool(changed))

# ---------------------------------------------------------------------------------------------------------
# 9. A store that took changes (docs/changes.md): the changes folder's revision files, delta and base
# stores, id files; kills of `update` and `compact`; readers of a revision while a writer commits; bad
# arguments of the change commands.

# Objects the fixture's batches add (two of one name, for a replace that must be refused), replace and add.
CHANGE_ADD = [("add_%d" % i, (20.0 + 25 * i, -10.0 + 4 * (i % 5), 5.0 + 2 * (i % 3)), 1.0 + 0.5 * (i % 3))
              for i in range(10)] + [("dup", (100.0, 0.0, 10.0), 2.0), ("dup", (150.0, 0.0, 10.0), 2.0)]
CHANGE_REPLACE = [("add_%d" % i, (22.0 + 25 * i, 5.0, 12.0), 3.0) for i in (1, 4, 7)]
CHANGE_CHECK_ADD = [("late_%d" % i, (40.0 + 30 * i, -5.0, 8.0), 1.5) for i in range(4)]
# The fixture: revision 0 the build, then (with keep 5 set by the compaction) revisions 2..6 kept.
CHANGE_BATCHES = [
    ("update", "s.mkt", "--add", "a.obj", "--message", "add", "--compact-threshold", "0"),
    ("update", "s.mkt", "--remove-ids", "7,100,2000", "--remove-names", "names.txt", "--message", "remove",
     "--compact-threshold", "0"),
    ("update", "s.mkt", "--replace", "r.obj", "--message", "replace", "--compact-threshold", "0"),
    ("compact", "s.mkt", "--keep", "5"),
    ("update", "s.mkt", "--add", "tanker:50:9", "--message", "add tanker", "--compact-threshold", "0"),
    ("update", "s.mkt", "--remove-ids", "3003,10", "--replace", "r.obj", "--message", "remove and replace",
     "--compact-threshold", "0"),
]
CHANGE_KEPT = [2, 3, 4, 5, 6]
CHECK_UPDATE = ("update", "s.mkt", "--add", "b.obj", "--compact-threshold", "0")
LEFTOVER_RE = re.compile(r"\.tmp\.|\.relink$|\.stale\.")


def copy_changed_store(src, dst, name="s.mkt"):
    """Copies STORE and STORE.changes (hard links between them kept, as the engine made them)."""
    dst.mkdir(parents=True, exist_ok=True)
    subprocess.run(["cp", "-a", str(src / "s.mkt"), str(src / "s.mkt.changes"), str(dst)], check=True)
    if name != "s.mkt":
        os.rename(dst / "s.mkt", dst / name)
        os.rename(dst / "s.mkt.changes", dst / (name + ".changes"))


def revision_files_named(folder):
    """{revision file: [files it names]} for every parsable revision file of a changes folder."""
    out = {}
    for n in sorted(os.listdir(folder)):
        if not re.match(r"^rev-\d{12}\.rev$", n):
            continue
        names = []
        for line in (Path(folder) / n).read_text(errors="replace").splitlines():
            w = line.split()
            # A delta line of format 2 ends in the shard it was routed to (docs/changes.md, "On disk").
            if w and (w[0] == "base" and len(w) == 9 or w[0] == "delta" and len(w) in (9, 10)):
                names += [w[2], w[5]]
            elif w and w[0] in ("removal", "touched") and len(w) == 6:
                names.append(w[2])
        names = [x for x in names if x != "-"]
        # A sharded base (a manifest) names its shard files, beside it in the folder: the build's
        # "<store>.shard-N.{mkt,ids}" for the first base, "<base>.shard-N.{mkt,ids}" for a compaction's.
        for base in [w.split()[2] for w in (Path(folder) / n).read_text(errors="replace").splitlines()
                     if w.startswith("base ") and len(w.split()) == 9]:
            if (Path(folder) / base).is_file() and (Path(folder) / base).read_bytes()[:8] == b"MKTSHARD":
                stem = re.escape(Path(folder).name[:-len(".changes")] if base == "base-0.mkt" else base)
                names += [x for x in sorted(os.listdir(folder))
                          if re.match(r"^%s\.shard-\d+\.(mkt|ids)$" % stem, x)]
        out[n] = names
    return out


def changes_leftovers(d, store="s.mkt"):
    """What is wrong with a store's folder after a successful writer: temporaries, unnamed or missing files."""
    probs = []
    top = sorted(n for n in os.listdir(d) if n.startswith(store) and n not in (store, store + ".changes"))
    if top:
        probs.append("beside the store: " + ", ".join(top[:4]))
    folder = Path(d) / (store + ".changes")
    if not folder.is_dir():
        return probs + ["no changes folder"]
    named = revision_files_named(folder)
    want = set(named) | {x for v in named.values() for x in v}
    have = set(os.listdir(folder))
    tmp = sorted(n for n in have if LEFTOVER_RE.search(n))
    if tmp:
        probs.append("temporaries in the folder: " + ", ".join(tmp[:4]))
    extra = sorted(have - want - set(tmp))
    if extra:
        probs.append("files no kept revision names: " + ", ".join(extra[:4]))
    missing = sorted(want - have)
    if missing:
        probs.append("named but missing: " + ", ".join(missing[:4]))
    return probs


class ChangeFixture:
    """A tanker:3000 store of one backend after CHANGE_BATCHES, with each kept revision's pristine answers."""

    def __init__(self, h, backend, scene="tanker:3000", tag="main", shards=0):
        self.h, self.backend, self.scene, self.shards = h, backend, scene, shards
        self.dir = h.fix / ("changes_%s_%s" % (tag, backend))
        self.qfile = changes_queries(h)
        if self.dir.exists():
            shutil.rmtree(self.dir)
        self.dir.mkdir(parents=True)
        write_change_inputs(self.dir)
        h.must("build", scene, "-o", "s.mkt", "--backend", backend, "-q",
               *(["--shards", str(shards)] if shards else []), cwd=self.dir)
        self.built = self.query(self.dir)
        for b in CHANGE_BATCHES:
            h.must(*b, cwd=self.dir)
        self.answers = {r: self.query(self.dir, r) for r in CHANGE_KEPT}
        self.one_q = changes_one_query(h, self.qfile)
        self.one = self.query(self.dir, qfile=self.one_q)
        self.newest = CHANGE_KEPT[-1]
        self.log = h.must("log", "s.mkt", cwd=self.dir).out
        self.log_json = h.must("log", "s.mkt", "--json", cwd=self.dir).out
        self.info = json.loads(h.must("info", "s.mkt", "--json", cwd=self.dir).out)
        self.since = self.clash_since(self.dir)
        self.next = self.after([CHECK_UPDATE], "next")  # the answers after the check update
        self.next_since = self.after([CHECK_UPDATE], "next", since=True)

    def clash_since(self, d):
        return sorted(self.h.must("clash", "s.mkt", "--since", CHANGE_KEPT[1], cwd=d).out.splitlines())

    def query(self, d, revision=None, qfile=None):
        args = ["query", "s.mkt", "--queries", qfile or self.qfile] + (
            ["--revision", revision] if revision is not None else [])
        return parse_answers(self.h.must(*args, cwd=d).out)

    def after(self, commands, name, qfile=None, since=False):
        """The newest answers (or clash --since lines) after running commands on a copy of the fixture."""
        d = self.h.fix / ("changes_%s_%s" % (name, self.backend))
        if d.exists():
            shutil.rmtree(d)
        copy_changed_store(self.dir, d)
        write_change_inputs(d)
        for cmd in commands:
            self.h.must(*cmd, cwd=d)
        a = self.clash_since(d) if since else self.query(d, qfile=qfile)
        shutil.rmtree(d)
        return a

    def folder_files(self):
        return sorted(os.listdir(self.dir / "s.mkt.changes"))


def write_change_inputs(d):
    d = Path(d)
    d.joinpath("a.obj").write_text(cube_obj(CHANGE_ADD))
    d.joinpath("r.obj").write_text(cube_obj(CHANGE_REPLACE))
    d.joinpath("b.obj").write_text(cube_obj(CHANGE_CHECK_ADD))
    d.joinpath("names.txt").write_text("add_2\nplate_000005\n")


def changes_queries(h):
    """tanker3000.q plus points and boxes on the objects the batches add and replace."""
    path = h.fix / "changes.q"
    if path.exists():
        return path
    base = h.queries_for(h.store("pagefile"), "tanker3000.q")
    qs = []
    for _, c, s in CHANGE_ADD + CHANGE_REPLACE + CHANGE_CHECK_ADD:
        qs.append(list(c))
        qs.append([c[i] - s for i in range(3)] + [c[i] + s for i in range(3)])
    write_queries(path, qs)
    path.write_text(base.read_text() + "".join(l + "\n" for l in path.read_text().splitlines()[1:]))
    return path


def changes_one_query(h, qfile):
    """Two queries: the first of qfile (a tanker object's centre) and the centre of an added object."""
    path = h.fix / "changes_one.q"
    first = [l for l in qfile.read_text().splitlines() if l and not l.startswith("#")][0]
    c = CHANGE_ADD[9][1]
    path.write_text("%s\npoint %.9g %.9g %.9g\n" % (first, c[0], c[1], c[2]))
    return path


def _answer_check(*wants):
    """exit 0 must print one of the given answer sets (the first is named in the difference)."""
    def f(p):
        try:
            got = parse_answers(p.out)
        except (ValueError, KeyError) as e:
            return "unparsable query output (%s)" % e
        if any(diff_answers(got, w) is None for w in wants):
            return None
        return diff_answers(got, wants[0])
    return f


def _shifted_answer_check(want, old_ids, most):
    """exit 0 must print `want` with every id not in `old_ids` (the objects added since) higher by one shift
    from 0 to `most`: a writer killed after some of its batch's id files were written gave those ids, and
    the next writer numbers above the highest (docs/changes.md); a sharded store's batch writes an id file
    per shard, so any part of the killed batch's ids may have been given."""
    def f(p):
        try:
            got = parse_answers(p.out)
        except (ValueError, KeyError) as e:
            return "unparsable query output (%s)" % e
        new_got = [i for _, _, hits in got for i in hits if i not in old_ids]
        new_want = [i for _, _, hits in want for i in hits if i not in old_ids]
        shift = min(new_got) - min(new_want) if new_got and new_want else 0
        if not 0 <= shift <= most:
            shift = 0
        shifted = [(q, k, sorted(i if i in old_ids else i + shift for i in hits)) for q, k, hits in want]
        return diff_answers(got, shifted)
    return f


def _info_check(want, sharded=False):
    def f(p):
        # a sharded store's info has the manifest's keys (docs/cli.md): compared whole with the pristine one's
        why = None if sharded else check_info_json(p.out, extra_allowed=(
            "revision", "base_objects", "delta_stores", "delta_objects", "removed_ids"))
        if why:
            return why
        j = json.loads(p.out)
        a = {k: v for k, v in j.items() if k not in ("file", "file_bytes")}
        b = {k: v for k, v in want.items() if k not in ("file", "file_bytes")}
        diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
        return None if not diff else "info --json differs from the pristine revision's in %s" % diff[:5]
    return f


def _since_check(want):
    return lambda p: None if sorted(p.out.splitlines()) == want else "clash --since: %d lines, expected %d" % (
        len(p.out.splitlines()), len(want))


def _text_check(want, what):
    return lambda p: None if p.out == want else "%s differs from the pristine store's" % what


def _flip(path, pos, x):
    b = bytearray(path.read_bytes())
    b[pos] ^= x
    _rewrite(path, b)


def _rewrite(path, data):
    """Writes over the file's own inode (a hard link of it, the store file, sees the damage too)."""
    with open(path, "r+b") as f:
        f.seek(0)
        f.write(data)
        f.truncate(len(data))


def change_corruptions(fx, other):
    """[(title, damaged names, how (shell), mutate(case dir), kind)]: damage to one file kind of the folder."""
    F = "s.mkt.changes/"
    rev = lambda r: "rev-%012d.rev" % r
    files = fx.folder_files()
    delta_new = next(n for n in files if n.startswith("delta-5-") and n.endswith(".mkt"))
    delta_old = next(n for n in files if n.startswith("delta-3-") and n.endswith(".mkt"))
    delta_6 = next(n for n in files if n.startswith("delta-6-") and n.endswith(".mkt"))
    base4 = next(n for n in files if n.startswith("base-4-") and n.endswith(".mkt"))
    ids_new = delta_new[:-4] + ".ids"
    ids_base = base4[:-4] + ".ids"  # (a sharded base has none: its manifest names its shards' id files)
    removed = next(n for n in files if n.startswith("removed-6-"))
    touched = next(n for n in files if n.startswith("touched-6-"))
    out = []

    def flip(name, pos, x):
        def f(d):
            p = d / F / name
            _flip(p, pos if pos >= 0 else p.stat().st_size + pos, x)
        return ("%s: byte %d xor 0x%02x" % (name, pos, x), [name],
                "python3 -c \"import sys; p='%s%s'; b=bytearray(open(p,'rb').read()); b[%d]^=%d; "
                "open(p,'r+b').write(b)\"" % (F, name, pos, x), f)

    def truncate(name, frac):
        def f(d):
            p = d / F / name
            os.truncate(p, int(p.stat().st_size * frac))
        return ("%s: truncated to %d%%" % (name, frac * 100), [name], "truncate (%.2f of its size) %s%s" %
                (frac, F, name), f)

    def zero(name, pos, n):
        if pos >= 0 and not name.startswith("rev-"):  # a block that holds data (zeros over zeros change nothing)
            data = (fx.dir / F / name).read_bytes()
            while pos + n < len(data) and not any(data[pos:pos + n]):
                pos += n

        def f(d):
            p = d / F / name
            b = bytearray(p.read_bytes())
            at = pos if pos >= 0 else max(0, len(b) + pos)
            b[at:at + n] = bytes(len(b[at:at + n]))
            _rewrite(p, b)
        return ("%s: %d zero bytes at %d" % (name, n, pos), [name], "dd if=/dev/zero of=%s%s bs=1 seek=%d count=%d "
                "conv=notrunc" % (F, name, pos, n), f)

    def delete(name):
        return ("%s: deleted" % name, [name], "rm %s%s" % (F, name), lambda d: os.unlink(d / F / name))

    def swap(a, b):
        def f(d):
            os.rename(d / F / a, d / F / "swap.tmp")
            os.rename(d / F / b, d / F / a)
            os.rename(d / F / "swap.tmp", d / F / b)
        return ("%s and %s swapped" % (a, b), [a, b], "swap %s%s %s%s" % (F, a, F, b), f)

    def foreign(src, name):
        def f(d):
            shutil.copyfile(other.dir / F / src, d / F / name)
        return ("%s of another store (tanker:3000:2, same batches) copied in as %s" % (src, name), [name],
                "cp other/%s%s %s%s" % (F, src, F, name), f)

    if fx.shards:
        # A sharded store: the compaction's base is a manifest (the store file's hard link) naming shard stores
        # and id files in the folder; the build's shards stay in the folder for revisions 0 and 1 (retired
        # here, so removed).
        shard_stores = [n for n in files if n.startswith(base4 + ".shard-") and n.endswith(".mkt")]
        shard_ids = [n for n in files if n.startswith(base4 + ".shard-") and n.endswith(".ids")]
        for name in shard_stores:
            size = (fx.dir / F / name).stat().st_size
            out.append(flip(name, 100, 0x04) + ("sharded",))
            out.append(flip(name, size // 2, 0x40) + ("sharded",))
            out.append(flip(name, size - 100, 0x08) + ("sharded",))
            out.append(truncate(name, 0.6) + ("sharded",))
            out.append(delete(name) + ("sharded",))
            out.append(foreign(name, name) + ("sharded",))
        for name in shard_ids:
            size = (fx.dir / F / name).stat().st_size
            out.append(flip(name, size - 3, 0x02) + ("sharded",))
            out.append(truncate(name, 0.5) + ("sharded",))
            out.append(delete(name) + ("sharded",))
            out.append(foreign(name, name) + ("sharded",))
        msize = (fx.dir / F / base4).stat().st_size
        out.append(flip(base4, 20, 0x01) + ("sharded",))
        out.append(flip(base4, msize // 2, 0x10) + ("sharded",))
        out.append(truncate(base4, 0.5) + ("sharded",))
        out.append(foreign(base4, base4) + ("sharded",))
        for name in (delta_new, ids_new):
            out.append(flip(name, (fx.dir / F / name).stat().st_size // 2, 0x40) + ("sharded",))
        out.append(flip(rev(6), 40, 0x01) + ("sharded",))
        out.append(delete(rev(4)) + ("sharded",))
        return out
    # revision files: the newest and two older ones (a batch's and the compaction's)
    for r in (6, 4, 3):
        n = rev(r)
        out.append(flip(n, 40, 0x01) + ("rev",))          # in the history/revision lines
        out.append(flip(n, -30, 0x10) + ("rev",))         # in the checksum line
        out.append(flip(n, -60, 0x20) + ("rev",))         # in the last file line
        out.append(truncate(n, 0.5) + ("rev",))
        out.append(truncate(n, 0.0) + ("rev",))
        out.append(zero(n, 100, 64) + ("rev",))
        out.append(delete(n) + ("rev",))
    out.append(swap(rev(5), rev(6)) + ("rev",))
    out.append(swap(rev(3), rev(4)) + ("rev",))
    out.append(foreign(rev(6), rev(6)) + ("rev",))
    out.append(foreign(rev(6), rev(7)) + ("rev",))
    out.append(foreign(rev(4), rev(4)) + ("rev",))
    # delta and base stores: the newest revision's, an older revision's, the compaction's base (the store file's
    # hard link: the store file is damaged with it)
    for name in (delta_new, delta_6, delta_old):
        size = (fx.dir / F / name).stat().st_size
        out.append(flip(name, 100, 0x04) + ("delta",))
        out.append(flip(name, size // 2, 0x40) + ("delta",))
        out.append(flip(name, size - 100, 0x08) + ("delta",))
        out.append(truncate(name, 0.6) + ("delta",))
        out.append(zero(name, 8192, 4096) + ("delta",))
        out.append(delete(name) + ("delta",))
    bsize = (fx.dir / F / base4).stat().st_size
    # the compaction's base is the store file (a hard link): the first and last 64 KiB are in its fingerprint
    for pos in (20000, 50000, bsize - 50000, bsize - 20000):
        out.append(flip(base4, pos, 0x01) + ("delta",))
    out.append(flip(base4, bsize // 2, 0x01) + ("delta",))
    out.append(flip(base4, bsize - 200, 0x80) + ("delta",))
    out.append(truncate(base4, 0.9) + ("delta",))
    out.append(foreign(delta_new, delta_new) + ("delta",))
    # id files
    for name in (ids_new, ids_base, removed, touched):
        size = (fx.dir / F / name).stat().st_size
        out.append(flip(name, size - 3, 0x02) + ("ids",))
        out.append(truncate(name, 0.5) + ("ids",))
        out.append(delete(name) + ("ids",))
    out.append(flip(ids_new, 2, 0x02) + ("ids",))
    out.append(foreign(ids_new, ids_new) + ("ids",))
    out.append(foreign(removed, removed) + ("ids",))
    return out


def case_numbering(h, cat):
    """next_case(title, row): the category's next case, numbered in order (None when --case skips it)."""
    counter = [0]

    def next_case(title, row):
        counter[0] += 1
        if not h.wanted(cat, counter[0]):
            return None
        return h.new_case(cat, counter[0], title, row=row)
    return next_case


def cat_changes_sharded(h):
    """The changes fixture on a sharded store (2 shards, paged file): its shard files damaged, its writers
    killed. Numbered on their own: the unsharded category's case ids stay as they were."""
    next_case = case_numbering(h, "changes-sharded")
    fx = ChangeFixture(h, "pagefile", tag="sharded", shards=2)
    other = ChangeFixture(h, "pagefile", scene="tanker:3000:2", tag="sharded_other", shards=2)
    changes_corrupt(h, fx, other, next_case)
    changes_kills(h, fx, next_case, row="changes-sharded-kills")


def cat_changes(h):
    next_case = case_numbering(h, "changes")
    for backend in ("pagefile", "hdf5"):
        fx = ChangeFixture(h, backend)
        other = ChangeFixture(h, backend, scene="tanker:3000:2", tag="other")
        changes_corrupt(h, fx, other, next_case)
        changes_store_swaps(h, fx, other, next_case)
        changes_kills(h, fx, next_case)
        changes_concurrency(h, fx, next_case)
        changes_args(h, fx, next_case)


def _revision_checks(c, fx, names, protect, revs=None, newest=None, log=True, update=True, next_want=None,
                     retired=None):
    """info, query, log, older revisions and an update on a (damaged) store: the pristine answers or clean
    errors; an update that succeeds must leave a store answering the pristine store's next revision."""
    kw = dict(names=names, protect=protect)
    newest = fx.newest if newest is None else newest
    c.mk("info", "s.mkt", "--json", check=_info_check(fx.info, fx.shards > 0), label="info --json", **kw)
    if not c.stopped():
        c.mk("query", "s.mkt", "--queries", "q.txt", check=_answer_check(fx.answers[newest]), label="query", **kw)
    if not c.stopped() and newest == fx.newest:
        # two queries only: a damaged page that the full query file reaches (and errors on) is not read
        shutil.copyfile(fx.one_q, c.path("one.q"))
        c.mk("query", "s.mkt", "--queries", "one.q", check=_answer_check(fx.one), label="query (2 points)", **kw)
    if log and not c.stopped():
        want_log = fx.log if retired is None else "".join(
            l for l in fx.log.splitlines(True) if not l.startswith("revision %d " % retired))
        c.mk("log", "s.mkt", check=_text_check(want_log, "log"), label="log", **kw)
    since_ok = False
    if newest == fx.newest and not c.stopped():
        since_ok = c.mk("clash", "s.mkt", "--since", CHANGE_KEPT[1], check=_since_check(fx.since),
                        label="clash --since %d" % CHANGE_KEPT[1], **dict(kw, names=kw["names"] + (
                            ["revision %d" % CHANGE_KEPT[1]] if retired == CHANGE_KEPT[1] else []))) == "ok"
    for r in (revs if revs is not None else CHANGE_KEPT[:-1]):
        if c.stopped():
            break
        c.mk("query", "s.mkt", "--queries", "q.txt", "--revision", r, check=_answer_check(fx.answers[r]),
             label="query --revision %d" % r, **dict(kw, names=kw["names"] + (["revision %d" % r] if r == retired
                                                                              else [])))
    if update and not c.stopped():
        before = snapshot(c.dir / "s.mkt.changes") if (c.dir / "s.mkt.changes").is_dir() else None
        st = c.mk(*CHECK_UPDATE, names=names, label="update --add b.obj", allow_new=["s.mkt.changes/*"],
                  outputs=["s.mkt"])
        p = c.steps[-1][1]
        if st == "clean" and before is not None and snapshot(c.dir / "s.mkt.changes") != before:
            c.record("update refused", p, "unclean", "the refused update changed the changes folder")
        if st == "ok":
            want = next_want if next_want is not None else fx.next
            c.mk("query", "s.mkt", "--queries", "q.txt", expect="succeed", names=names,
                 check=_answer_check(want), label="query after the update")
            if c.steps[-1][2] not in ("ok",):
                c.note("the update exited 0 over a damaged store and the revision it committed does not answer "
                       "as the pristine store's next revision")
            if retired != CHANGE_KEPT[1]:
                # must work after the update when it worked before it (revision 3's own damage stays)
                c.mk("clash", "s.mkt", "--since", CHANGE_KEPT[1], expect="succeed" if since_ok else "either",
                     names=names,
                     check=_since_check(fx.next_since), label="clash --since %d after the update" % CHANGE_KEPT[1])
            left = changes_leftovers(c.dir)
            if left:
                c.note("after the update: " + "; ".join(left))
            c.mk("log", "s.mkt", "--json", names=names, label="log --json after the update")
            try:
                revs = [json.loads(x)["revision"] for x in c.steps[-1][1].out.splitlines() if x.strip()]
            except (ValueError, KeyError):
                revs = None
            if c.steps[-1][2] == "ok" and revs is not None and (max(revs) != fx.newest + 1 or not set(
                    CHANGE_KEPT[1:]) - {retired} <= set(revs)):
                c.record("history", c.steps[-1][1], "wrong", "after the update the log has revisions %s, expected "
                         "%s and %d (history lost, or a revision number given twice)" % (revs, CHANGE_KEPT[1:],
                                                                                        fx.newest + 1))


def changes_corrupt(h, fx, other, next_case):
    for title, damaged, how, mutate, kind in change_corruptions(fx, other):
        c = next_case("%s%s: %s" % (fx.backend, ", 2 shards" if fx.shards else "", title), "changes-" + kind)
        if c is None:
            continue
        copy_changed_store(fx.dir, c.dir)
        write_change_inputs(c.dir)
        shutil.copyfile(fx.qfile, c.path("q.txt"))
        mutate(c.dir)
        c.note("pristine: the fixture (changes_main_%s: %s; then %s); then %s" % (
            fx.backend, fx.scene, " / ".join(" ".join(b) for b in CHANGE_BATCHES), how))
        c.say("# " + how)
        names = list(damaged) + ["s.mkt.changes/" + d for d in damaged]
        if any(d.startswith("base-") for d in damaged):
            names.append("s.mkt")  # the store file is a hard link of the newest base
        retired = None
        m = re.match(r"^rev-0*(\d+)\.rev: deleted$", title)
        if m and int(m.group(1)) != fx.newest:
            retired = int(m.group(1))  # an older revision file deleted: that revision is retired, no more
        _revision_checks(c, fx, names, protect=["s.mkt.changes/" + d for d in damaged if "rev-" in d],
                         retired=retired)
        h.finish_case(c)


def fresh_answers(h, fx, scene):
    """The answers of a fresh build of scene (no changes folder), and after the check update on it."""
    d = h.fix / ("changes_fresh_%s" % fx.backend)
    if d.exists():
        shutil.rmtree(d)
    d.mkdir()
    h.must("build", scene, "-o", "s.mkt", "--backend", fx.backend, "-q", cwd=d)
    first = fx.query(d)
    write_change_inputs(d)
    h.must(*CHECK_UPDATE, cwd=d)
    second = fx.query(d)
    shutil.rmtree(d)
    return first, second


def changes_store_swaps(h, fx, other, next_case):
    """The store file replaced (the folder then belongs to no store, or to an older base of its own), the
    folder replaced by a file, the store rebuilt over its changes."""
    plain = h.store(fx.backend, "tanker:3000:2")
    plain_answers, plain_next = fresh_answers(h, fx, "tanker:3000:2")
    built_next = fresh_answers(h, fx, fx.scene)[1]

    def new_store_checks(c, want, want_next, names):
        c.mk("info", "s.mkt", "--json", names=names, label="info --json",
             check=lambda p: check_info_json(p.out, extra_allowed=("revision", "base_objects", "delta_stores",
                                                                    "delta_objects", "removed_ids")))
        c.mk("query", "s.mkt", "--queries", "q.txt", names=names, check=_answer_check(want), label="query")
        c.mk("log", "s.mkt", names=names, label="log",
             check=lambda p: None if len(p.out.splitlines()) == 1 and p.out.startswith("revision 0 ")
             else "log of a store whose folder belongs to no store: %r" % p.out[:200])
        for r in (3, 6):
            c.mk("query", "s.mkt", "--queries", "q.txt", "--revision", r, expect="fail",
                 names=["revision %d" % r], label="query --revision %d (the old folder's)" % r)
        c.mk(*CHECK_UPDATE, names=names, label="update --add b.obj",
             allow_new=["s.mkt.changes", "s.mkt.changes/*"], outputs=["s.mkt"])
        if c.steps[-1][2] == "ok":
            c.mk("query", "s.mkt", "--queries", "q.txt", expect="succeed", names=names,
                 check=_answer_check(want_next), label="query after the update")
            left = changes_leftovers(c.dir)
            if left:
                c.record("leftovers", c.steps[-1][1], "unclean", "; ".join(left))

    def setup(title):
        c = next_case("%s: %s" % (fx.backend, title), "changes-store")
        if c is None:
            return None
        copy_changed_store(fx.dir, c.dir)
        write_change_inputs(c.dir)
        shutil.copyfile(fx.qfile, c.path("q.txt"))
        return c

    c = setup("store file replaced by another store (tanker:3000:2, no changes)")
    if c:
        os.unlink(c.path("s.mkt"))
        shutil.copyfile(plain, c.path("s.mkt"))
        c.say("# cp <tanker:3000:2 store> s.mkt (a new inode; the folder stays)")
        new_store_checks(c, plain_answers, plain_next, ["s.mkt"])
        h.finish_case(c)
    c = setup("store file overwritten in place by another store (the folder's base is damaged with it)")
    if c:
        _rewrite(c.path("s.mkt"), plain.read_bytes())
        c.say("# dd <tanker:3000:2 store> over s.mkt in place (the hard link in the folder too)")
        c.mk("info", "s.mkt", "--json", names=["s.mkt"], label="info --json",
             check=lambda p: check_info_json(p.out, extra_allowed=("revision", "base_objects", "delta_stores",
                                                                    "delta_objects", "removed_ids")))
        c.mk("query", "s.mkt", "--queries", "q.txt", names=["s.mkt"], check=_answer_check(plain_answers),
             label="query")
        for r in (3, 6):
            c.mk("query", "s.mkt", "--queries", "q.txt", "--revision", r, names=["s.mkt", "base-"],
                 check=_answer_check(fx.answers[r]), label="query --revision %d" % r)
        c.mk(*CHECK_UPDATE, names=["s.mkt"], label="update --add b.obj", allow_new=["s.mkt.changes/*"],
             outputs=["s.mkt"])
        if c.steps[-1][2] == "ok":
            c.mk("query", "s.mkt", "--queries", "q.txt", expect="succeed", names=["s.mkt"],
                 check=_answer_check(plain_next), label="query after the update")
        h.finish_case(c)
    c = setup("store file replaced by the folder's older base (revision 2's base-0.mkt)")
    if c:
        os.unlink(c.path("s.mkt"))
        shutil.copyfile(c.path("s.mkt.changes/base-0.mkt"), c.path("s.mkt"))
        c.say("cp s.mkt.changes/base-0.mkt s.mkt")
        _revision_checks(c, fx, ["s.mkt", "base-0.mkt"], protect=[])
        h.finish_case(c)
    c = setup("the store rebuilt over its changes (mktree build tanker:3000 -o s.mkt)")
    if c:
        c.mk("build", "tanker:3000", "-o", "s.mkt", "--backend", fx.backend, "-q", expect="succeed",
             names=["s.mkt"], outputs=["s.mkt"], allow_new=["s.mkt.changes", "s.mkt.changes/*"],
             label="build over the store")
        new_store_checks(c, fx.built, built_next, ["s.mkt"])
        h.finish_case(c)
    c = setup("the store rebuilt from another scene over its changes (mktree build tanker:3000:2 -o s.mkt)")
    if c:
        c.mk("build", "tanker:3000:2", "-o", "s.mkt", "--backend", fx.backend, "-q", expect="succeed",
             names=["s.mkt"], outputs=["s.mkt"], allow_new=["s.mkt.changes", "s.mkt.changes/*"],
             label="build over the store")
        new_store_checks(c, plain_answers, plain_next, ["s.mkt"])
        h.finish_case(c)
    for what in ("a file", "an empty folder", "a symbolic link to a missing folder"):
        c = setup("the changes folder replaced by %s" % what)
        if c is None:
            continue
        shutil.rmtree(c.path("s.mkt.changes"))
        if what == "a file":
            c.path("s.mkt.changes").write_text("not a folder\n")
        elif what == "an empty folder":
            c.path("s.mkt.changes").mkdir()
        else:
            os.symlink("missing-folder", c.path("s.mkt.changes"))
        c.say("rm -r s.mkt.changes; # then make it " + what)
        names = ["s.mkt.changes", "s.mkt"]
        # the store file is the compaction's base: alone it is a store, but not the revisions' (ids differ)
        for args, label in ((("info", "s.mkt", "--json"), "info --json"),
                            (("query", "s.mkt", "--queries", "q.txt"), "query"), (("log", "s.mkt"), "log"),
                            (("query", "s.mkt", "--queries", "q.txt", "--revision", 6), "query --revision 6"),
                            (CHECK_UPDATE, "update --add b.obj")):
            c.mk(*args, names=names, label=label, allow_new=["s.mkt.changes/*"], outputs=["s.mkt"])
            if c.steps[-1][2] == "ok" and label.startswith("query"):
                c.note("%s answered (exit 0) with the changes folder gone" % label)
        h.finish_case(c)


def changes_kills(h, fx, next_case, row="changes-kills"):
    """update (with and without its threshold compaction) and compact killed by SIGKILL at random times."""
    big = "tanker:3000:5"
    add_cmd = ("update", "s.mkt", "--add", big, "--compact-threshold", "0")
    add_auto = ("update", "s.mkt", "--add", big)
    a1 = fx.after([add_cmd], "kill1")
    a1b = fx.after([add_cmd, CHECK_UPDATE], "kill1b")
    plans = [("update --add %s" % big, add_cmd, [fx.answers[fx.newest], a1], [fx.next, a1b]),
             ("update --add %s with its threshold compaction" % big, add_auto, [fx.answers[fx.newest], a1],
              [fx.next, a1b]),
             ("compact", ("compact", "s.mkt"), [fx.answers[fx.newest]], [fx.next])]
    for title, cmd, wants, wants_next in plans:
        d = h.work / "kill-timing"
        if d.exists():
            shutil.rmtree(d)
        copy_changed_store(fx.dir, d)
        t0 = time.monotonic()
        p = run([str(h.mktree)] + list(cmd), d, 120)
        dur = time.monotonic() - t0
        shutil.rmtree(d)
        if p.rc != 0:
            raise SetupError("kill timing: %s: %s" % (" ".join(cmd), p.err.strip()[-200:]))
        for k in range(12):
            r = h.rng("changes-kill", fx.backend, title, k)
            at = r.uniform(0.002, dur * 1.05) if k % 2 == 0 else r.uniform(0.8 * dur, 1.02 * dur)
            c = next_case("%s: kill -9 at %.3f s of a %.3f s %s" % (fx.backend, at, dur, title), row)
            if c is None:
                continue
            copy_changed_store(fx.dir, c.dir)
            write_change_inputs(c.dir)
            shutil.copyfile(fx.qfile, c.path("q.txt"))
            c.save_inputs()
            argv = [str(h.mktree)] + list(cmd)
            c.say("$MKTREE %s & sleep %.3f; kill -9 $!" % (shlex.join(argv[1:]), at))
            p = spawn(argv, c.dir)
            time.sleep(at)
            try:
                os.killpg(p.popen.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            finish(p, h.timeout)
            c.note("the writer %s" % ("was killed" if p.sig == signal.SIGKILL else "had ended: " + p.status()))
            if p.exited and p.rc != 0:
                c.record("writer (killed)", p, "unclean", "failed before the kill: " + p.err.strip()[-200:])
            elif p.sig not in (None, signal.SIGKILL):
                c.record("writer (killed)", p, "crash", "killed by " + signal.Signals(p.sig).name)
            left = sorted(os.listdir(c.path("s.mkt.changes")))
            extra = sorted(set(left) - set(fx.folder_files()))
            if extra:
                c.note("left in the folder by the kill: " + ", ".join(extra[:8]))
            c.mk("query", "s.mkt", "--queries", "q.txt", expect="succeed", names=["s.mkt"],
                 check=_answer_check(*wants), label="query after the kill")
            committed = c.steps[-1][2] == "ok" and len(wants) > 1 and \
                diff_answers(parse_answers(c.steps[-1][1].out), wants[1]) is None
            c.mk("query", "s.mkt", "--queries", "q.txt", "--revision", fx.newest, expect="succeed", names=["s.mkt"],
                 check=_answer_check(fx.answers[fx.newest]), label="query --revision %d" % fx.newest)
            c.mk("log", "s.mkt", "--json", expect="succeed", names=["s.mkt"], label="log --json")
            try:
                revs = [json.loads(x)["revision"] for x in c.steps[-1][1].out.splitlines() if x.strip()]
                newest = max(revs)
                if not fx.newest <= newest <= fx.newest + 2:
                    c.record("log", c.steps[-1][1], "wrong", "newest revision %d after the kill" % newest)
                c.note("newest revision after the kill: %d%s" % (newest, ", the batch committed" if committed else ""))
            except (ValueError, KeyError):
                c.record("log", c.steps[-1][1], "wrong", "log --json unparsable")
            c.mk(*CHECK_UPDATE, expect="succeed", names=["s.mkt"], label="the next update",
                 allow_new=["s.mkt.changes/*"], outputs=["s.mkt"])
            if c.steps[-1][2] == "ok":
                # A writer killed after its batch's id files were written gave those ids: the next writer
                # numbers its objects above them (docs/changes.md), so the check update's objects may have
                # ids 3000 higher (the killed batch's size).
                want = wants_next[1] if committed else wants_next[0]
                old_ids = {i for _, _, hits in fx.answers[fx.newest] for i in hits}
                c.mk("query", "s.mkt", "--queries", "q.txt", expect="succeed", names=["s.mkt"],
                     check=_shifted_answer_check(want, old_ids, 3000) if not committed else _answer_check(want),
                     label="query after the next update")
                left = changes_leftovers(c.dir)
                if left:
                    c.record("leftovers", c.steps[-1][1], "unclean", "after the next update: " + "; ".join(left))
            h.finish_case(c)


def changes_concurrency(h, fx, next_case):
    """Readers of revisions in loops while a writer commits batches and compacts."""
    seq = [("update", "s.mkt", "--add", "tanker:500:3", "--compact-threshold", "0"),
           ("compact", "s.mkt"),
           ("update", "s.mkt", "--remove-ids", "3005,20,21", "--replace", "r.obj", "--compact-threshold", "0"),
           ("update", "s.mkt", "--add", "tanker:300:4", "--compact-threshold", "0.05")]
    # the newest answers after each writer step (a compaction answers as the revision before it)
    steps = [fx.answers[fx.newest]] + [fx.after(seq[:i + 1], "conc%d" % i) for i in range(len(seq))]
    keep = 5
    for k in range(4):
        c = next_case("%s: readers of revisions %d and %d and of the newest while 4 writer steps (update, compact, "
                      "update, update with its threshold compaction) run (%d)"
                      % (fx.backend, fx.newest, fx.newest - 2, k), "changes-concurrency")
        if c is None:
            continue
        copy_changed_store(fx.dir, c.dir)
        write_change_inputs(c.dir)
        shutil.copyfile(fx.qfile, c.path("q.txt"))
        c.save_inputs()
        c.say("(for a in %s; do $MKTREE $a; done) &  # the writer steps, as listed" %
              " ".join(shlex.quote(" ".join(s)) for s in seq))
        c.say("while kill -0 $! 2>/dev/null; do $MKTREE query s.mkt --queries q.txt --revision R; done  # R = %d, "
              "%d, newest" % (fx.newest, fx.newest - 2))
        stop, results, errors = [], [], []
        delay = 0.05 * k

        def writer():
            time.sleep(delay)
            for s in seq:
                p = run([str(h.mktree)] + list(s), c.dir, 60)
                results.append((s, p))
                if p.rc != 0:
                    break
            stop.append(1)

        def reader(rev):
            runs, retired = 0, False
            while True:
                done = bool(stop)
                argv = [str(h.mktree), "query", "s.mkt", "--queries", "q.txt"] + (
                    ["--revision", str(rev)] if rev is not None else [])
                p = run(argv, c.dir, h.timeout)
                runs += 1
                if not p.exited:
                    errors.append(("hang" if p.timed_out else "crash", "reader of %s: %s" % (rev, p.status()), p))
                    break
                if p.rc != 0:
                    # a revision past the keep window may be retired (no reader held it between two runs)
                    if rev is not None and "is not kept" in p.err and \
                            error_line_problem(p.err, ["revision %d" % rev]) is None:
                        retired = True
                    else:
                        errors.append(("unclean", "reader of %s: %s: %s" % (rev, p.status(), p.err.strip()[-200:]),
                                       p))
                        break
                else:
                    if retired:
                        errors.append(("wrong", "reader of %s answered after being told it is not kept" % rev, p))
                        break
                    got = parse_answers(p.out)
                    wants = [fx.answers[rev]] if rev is not None else steps
                    if not any(diff_answers(got, w) is None for w in wants):
                        errors.append(("wrong", "reader of %s: %s" % (rev, diff_answers(got, wants[0])), p))
                        break
                if done:
                    break
            readers_runs.append((rev, runs, retired))

        readers_runs = []
        threads = [threading.Thread(target=writer)] + [threading.Thread(target=reader, args=(r,))
                                                        for r in (fx.newest, fx.newest - 2, None)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        c.note("reader runs: " + ", ".join("revision %s: %d%s" % (r if r is not None else "newest", n,
                                                                   " (then retired)" if ret else "")
                                           for r, n, ret in readers_runs))
        for s, p in results:
            if p.rc != 0 or not p.exited:
                c.record("writer " + " ".join(s[:2]), p, "crash" if p.sig else "hang" if p.timed_out else "unclean",
                         "a writer step failed: %s: %s" % (p.status(), p.err.strip()[-200:]))
        for v, why, p in errors:
            c.record("readers", p, v, why)
        if not c.steps:
            c.record("readers", results[-1][1], "ok", "")
        c.mk("query", "s.mkt", "--queries", "q.txt", expect="succeed", names=["s.mkt"],
             check=_answer_check(steps[-1]), label="query the end")
        left = changes_leftovers(c.dir)
        if left:
            c.record("leftovers", c.steps[-1][1], "unclean", "; ".join(left))
        h.finish_case(c)
    # one long reader of the oldest kept revision holds it while the writer retires past it
    c = next_case("%s: a long reader of revision %d (the oldest kept) while 4 writer steps retire it" % (
        fx.backend, CHANGE_KEPT[0]), "changes-concurrency")
    if c is not None:
        copy_changed_store(fx.dir, c.dir)
        write_change_inputs(c.dir)
        q = fx.qfile.read_text().splitlines()[1:]
        c.path("long.q").write_text("".join(l + "\n" for l in q * 40))
        c.save_inputs()
        old = CHANGE_KEPT[0]
        want_long = fx.answers[old]
        argv = [str(h.mktree), "query", "s.mkt", "--queries", "long.q", "--revision", str(old), "--cold",
                "--cache-pages", "0"]
        c.say("$MKTREE %s &  # while the writer steps run" % shlex.join(argv[1:]))
        rp = spawn(argv, c.dir)
        time.sleep(0.3)
        wr = []
        for s in seq:
            wr.append((s, run([str(h.mktree)] + list(s), c.dir, 60)))
        reader_was_running = rp.popen.poll() is None
        finish(rp, 4 * h.timeout)
        c.note("the reader %s still running when the writer ended" % ("was" if reader_was_running else "was not"))
        for s, p in wr:
            if p.rc != 0:
                c.record("writer " + " ".join(s[:2]), p, "unclean", "%s: %s" % (p.status(), p.err.strip()[-200:]))
        if rp.rc != 0 or not rp.exited:
            c.record("long reader", rp, "crash" if rp.sig else "hang" if rp.timed_out else "unclean",
                     "%s: %s" % (rp.status(), rp.err.strip()[-200:]))
        else:
            got = parse_answers(rp.out)
            n = len(want_long)
            bad = [i for i in range(len(got)) if got[i][2] != want_long[i % n][2]]
            c.record("long reader", rp, "wrong" if bad or len(got) != 40 * n else "ok",
                     "%d of %d answers differ from revision %d's" % (len(bad), len(got), old) if bad or
                     len(got) != 40 * n else "")
        def long_check(p):
            got = parse_answers(p.out)
            n = len(want_long)
            bad = [i for i in range(len(got)) if got[i][2] != want_long[i % n][2]]
            return "%d answers differ from revision %d's" % (len(bad), old) if bad or len(got) != 40 * n else None
        c.mk("query", "s.mkt", "--queries", "long.q", "--revision", old, names=["revision %d" % old],
             check=long_check, label="revision %d after the reader let it go (kept until the next commit)" % old)
        c.mk(*CHECK_UPDATE, expect="succeed", names=["s.mkt"], label="the next update",
             allow_new=["s.mkt.changes/*"], outputs=["s.mkt"])
        c.mk("query", "s.mkt", "--queries", "long.q", "--revision", old, expect="fail", names=["revision %d" % old],
             label="revision %d after the next commit" % old)
        left = changes_leftovers(c.dir)
        if left:
            c.record("leftovers", c.steps[-1][1], "unclean", "; ".join(left))
        h.finish_case(c)


def changes_args(h, fx, next_case):
    """Bad arguments of update, log, compact and --revision: one error line naming the thing, exit non-zero,
    the store unchanged (every file, and `mktree log`)."""
    cases = [
        ("update: unknown id", ("update", "s.mkt", "--remove-ids", "99999"), ["99999"], {}),
        ("update: an id removed before", ("update", "s.mkt", "--remove-ids", "7"), ["7"], {}),
        ("update: an id above every id given", ("update", "s.mkt", "--remove-ids", "4294967295"), ["4294967295"], {}),
        ("update: an id that is not a number", ("update", "s.mkt", "--remove-ids", "12,x3"), ["x3"], {}),
        ("update: an empty id", ("update", "s.mkt", "--remove-ids", "12,,13"), ["--remove-ids"], {}),
        ("update: an id removed twice", ("update", "s.mkt", "--remove-ids", "11,11"), ["11"], {}),
        ("update: an id removed and replaced", ("update", "s.mkt", "--remove-ids", "3001", "--replace", "r.obj"),
         ["3001", "add_1"], {}),
        ("update: missing names file", ("update", "s.mkt", "--remove-names", "missing.txt"), ["missing.txt"], {}),
        ("update: names file with an empty line", ("update", "s.mkt", "--remove-names", "n.txt"), ["n.txt:2"],
         {"n.txt": "add_3\n\nadd_5\n"}),
        ("update: names file, a name of no live object", ("update", "s.mkt", "--remove-names", "n.txt"),
         ["no_such_object"], {"n.txt": "add_5\nno_such_object\n"}),
        ("update: names file is a folder", ("update", "s.mkt", "--remove-names", "dir"), ["dir"], {"dir/": ""}),
        ("update: replace by a name no object has", ("update", "s.mkt", "--replace", "x.obj"), ["nope"],
         {"x.obj": cube_obj([("nope", (10.0, 0.0, 5.0), 1.0)])}),
        ("update: replace by a name two objects have", ("update", "s.mkt", "--replace", "x.obj"), ["dup"],
         {"x.obj": cube_obj([("dup", (10.0, 0.0, 5.0), 1.0)])}),
        ("update: replace by a removed object's name", ("update", "s.mkt", "--replace", "x.obj"), ["add_2"],
         {"x.obj": cube_obj([("add_2", (10.0, 0.0, 5.0), 1.0)])}),
        ("update: NaN in an --add OBJ", ("update", "s.mkt", "--add", "nan.obj"), ["nan.obj"],
         {"nan.obj": cube_obj([("n", (10.0, 0.0, 5.0), 1.0)]).replace("v 9.500000", "v nan", 1)}),
        ("update: inf in a --replace OBJ", ("update", "s.mkt", "--replace", "inf.obj"), ["inf.obj"],
         {"inf.obj": cube_obj([("add_1", (10.0, 0.0, 5.0), 1.0)]).replace("v 9.500000", "v inf", 1)}),
        ("update: a good add with a bad remove (nothing committed)",
         ("update", "s.mkt", "--add", "b.obj", "--remove-ids", "99999"), ["99999"], {}),
        ("update: missing --add scene", ("update", "s.mkt", "--add", "missing.obj"), ["missing.obj"], {}),
        ("update: --add tanker:0", ("update", "s.mkt", "--add", "tanker:0"), ["tanker:0"], {}),
        ("update: negative --compact-threshold", ("update", "s.mkt", "--add", "b.obj", "--compact-threshold", "-1"),
         ["--compact-threshold"], {}),
        ("update: missing store", ("update", "missing.mkt", "--add", "b.obj"), ["missing.mkt"], {}),
        ("query --revision of a retired revision", ("query", "s.mkt", "--queries", "q.txt", "--revision", "1"),
         ["revision 1"], {}),
        ("query --revision 0 (retired)", ("query", "s.mkt", "--queries", "q.txt", "--revision", "0"),
         ["revision 0"], {}),
        ("query --revision of a future revision", ("query", "s.mkt", "--queries", "q.txt", "--revision", "7"),
         ["revision 7"], {}),
        ("query --revision -1", ("query", "s.mkt", "--queries", "q.txt", "--revision", "-1"), ["--revision"], {}),
        ("query --revision 2^64", ("query", "s.mkt", "--queries", "q.txt", "--revision", "18446744073709551616"),
         ["--revision"], {}),
        ("info --revision of a future revision", ("info", "s.mkt", "--json", "--revision", "99"), ["revision 99"], {}),
        ("info --revision of a retired revision", ("info", "s.mkt", "--revision", "1"), ["revision 1"], {}),
        ("info --object of an id removed at that revision", ("info", "s.mkt", "--object", "7", "--revision", "4"),
         ["7"], {}),
        ("info --object of an id not yet given at that revision",
         ("info", "s.mkt", "--object", "3020", "--revision", "4"), ["3020"], {}),
        ("clash --revision of a retired revision", ("clash", "s.mkt", "--revision", "1"), ["revision 1"], {}),
        ("clash --since of a retired revision", ("clash", "s.mkt", "--since", "1"), ["revision 1"], {}),
        ("clash --since of a future revision", ("clash", "s.mkt", "--since", "9"), ["revision 9"], {}),
        ("collide --revision of a future revision", ("collide", "s.mkt", "--object", "b.obj", "--revision", "8"),
         ["revision 8"], {}),
        ("compact --keep 0", ("compact", "s.mkt", "--keep", "0"), ["--keep"], {}),
        ("compact --keep 1000001", ("compact", "s.mkt", "--keep", "1000001"), ["--keep"], {}),
        ("compact of a missing store", ("compact", "missing.mkt"), ["missing.mkt"], {}),
        ("log of a missing store", ("log", "missing.mkt"), ["missing.mkt"], {}),
        ("log of a folder", ("log", "dir"), ["dir"], {"dir/": ""}),
    ]
    for title, argv, names, files in cases:
        c = next_case("%s: %s" % (fx.backend, title), "changes-args")
        if c is None:
            continue
        copy_changed_store(fx.dir, c.dir)
        write_change_inputs(c.dir)
        shutil.copyfile(fx.qfile, c.path("q.txt"))
        for name, text in files.items():
            if name.endswith("/"):
                c.path(name).mkdir()
            else:
                c.path(name).write_text(text)
        protect = sorted(snapshot(c.dir))
        c.mk(*argv, expect="fail", names=names, protect=protect, label=" ".join(argv)[:70])
        c.mk("log", "s.mkt", expect="succeed", names=["s.mkt"], check=_text_check(fx.log, "log"), label="log after")
        h.finish_case(c)
    # a second update while one runs: refused at once, the first commits, the log has exactly the first
    for k in range(3):
        c = next_case("%s: a second update %d ms into a first (tanker:3000:5)" % (fx.backend, 30 + 40 * k),
                      "changes-args")
        if c is None:
            continue
        copy_changed_store(fx.dir, c.dir)
        write_change_inputs(c.dir)
        shutil.copyfile(fx.qfile, c.path("q.txt"))
        c.save_inputs()
        a = [str(h.mktree), "update", "s.mkt", "--add", "tanker:3000:5", "--compact-threshold", "0"]
        b = [str(h.mktree)] + list(CHECK_UPDATE)
        c.say("$MKTREE %s & sleep %.2f; $MKTREE %s; wait" % (shlex.join(a[1:]), (30 + 40 * k) / 1000,
                                                            shlex.join(b[1:])))
        pa = spawn(a, c.dir)
        time.sleep((30 + 40 * k) / 1000)
        pa_done = pa.popen.poll() is not None
        pb = finish(spawn(b, c.dir), h.timeout)
        finish(pa, h.timeout)
        c.note("first: %s; second: %s%s" % (pa.status(), pb.status(),
                                             "; the first had ended before the second started" if pa_done else ""))
        for label, p in (("first update", pa), ("second update", pb)):
            if not p.exited:
                c.record(label, p, "crash" if p.sig else "hang", p.status())
            elif p.rc != 0:
                e = error_line_problem(p.err, ["another writer"])
                c.record(label, p, "unclean" if e or p.rc != 1 else "clean", e or "")
        if pa.rc != 0 and pb.rc != 0:
            c.record("both updates", pb, "unclean", "neither update committed")
        if pa.rc == 0 and pb.rc == 0:
            c.note("both committed: the second took the lock before or after the first held it")
        c.mk("log", "s.mkt", "--json", expect="succeed", names=["s.mkt"], label="log after")
        try:
            revs = [json.loads(x) for x in c.steps[-1][1].out.splitlines() if x.strip()]
            added = [r["added"] for r in revs if r["revision"] > fx.newest]
            expect_added = ([3000] if pa.rc == 0 else []) + ([len(CHANGE_CHECK_ADD)] if pb.rc == 0 else [])
            if sorted(added) != sorted(expect_added):
                c.record("log", c.steps[-1][1], "wrong", "revisions after %d added %s, expected %s" % (
                    fx.newest, added, expect_added))
        except (ValueError, KeyError) as e:
            c.record("log", c.steps[-1][1], "wrong", "log --json unparsable: %s" % e)
        h.finish_case(c)


# ---------------------------------------------------------------------------------------------------------


RUNNERS = {"corrupt": cat_corrupt, "crafted": cat_crafted, "scenes": cat_scenes, "args": cat_args, "disk": cat_disk,
           "kills": cat_kills, "concurrency": cat_concurrency, "shards": cat_shards,
           "changes": cat_changes, "changes-sharded": cat_changes_sharded}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mktree", required=True, help="the mktree binary to test")
    ap.add_argument("--out", required=True, help="output folder (table.md, details.md, cases/)")
    ap.add_argument("--only", choices=CATEGORIES, action="append", help="run only this category (repeatable)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=10.0, help="seconds before a run counts as a hang")
    ap.add_argument("--case", help="run only this case id (e.g. crafted-014)")
    args = ap.parse_args()
    if args.case:
        args.only = [args.case.rsplit("-", 1)[0]]
    h = Harness(args)
    t0 = time.monotonic()
    cats = args.only or CATEGORIES

    def stop(signum, frame):
        h.cleanup()
        sys.exit(130)
    signal.signal(signal.SIGTERM, stop)
    try:
        for cat in cats:
            t = time.monotonic()
            print("%s: " % cat, end="", flush=True)
            try:
                RUNNERS[cat](h)
            except SetupError as e:
                h.setup_notes.append("%s stopped: %s" % (cat, e))
            print(" %.0f s" % (time.monotonic() - t), flush=True)
    finally:
        h.cleanup()
    table = h.report(time.monotonic() - t0)
    shutil.rmtree(h.work, ignore_errors=True)
    print()
    print(table)
    print("details: %s" % (h.out / "details.md"))


if __name__ == "__main__":
    main()
