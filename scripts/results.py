#!/usr/bin/python3
"""Regenerate the deterministic tables of docs/results.md from the code.

Each generated table sits in docs/results.md between two markers,

    <!-- results:NAME -->
    | ... the table ... |
    <!-- /results:NAME -->

and the command that makes it is shown just above it in the doc. This script
knows, for each NAME, the ropsim commands to run and how to format the table.
Only deterministic figures are generated (RMSE, cycles, bytes, counts: the same
inputs and seeds give the same text on any machine); host times are measured
by hand and never generated.

Each table is fast (seconds, built-in scenes only) or slow (studies that take
minutes, or inputs from ../shared/data/meshes).

    scripts/results.py --list                       # every table, fast or slow
    scripts/results.py --write [--fast] [--only NAME ...]   # rewrite tables in place
    scripts/results.py --check --fast               # exit 1 and a unified diff if a table differs

Options: --ropsim PATH (default: $ROPSIM, else build/ropsim), --doc PATH
(default: docs/results.md), -j N (ropsim processes at a time, default 2).
Run with /usr/bin/python3.
"""
# The tables and the runs they make live beside this file: results_tables.py
# (each table's generator, TABLES) and results_context.py (Context: the
# ropsim runs and studies); this file is the command line and the marker
# blocks of the doc (read, check, rewrite).
import argparse
import concurrent.futures
import difflib
import os
import re
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from results_context import ROOT, Context  # noqa: E402
from results_tables import TABLES  # noqa: E402

MARK_OPEN = "<!-- results:%s -->"
MARK_CLOSE = "<!-- /results:%s -->"
MARK_RE = re.compile(r"<!-- results:([A-Za-z0-9_.-]+) -->\n(.*?)<!-- /results:\1 -->\n", re.S)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", action="store_true", help="rewrite the tables in the doc")
    mode.add_argument("--check", action="store_true", help="exit 1 with a diff if a table differs from the code's")
    mode.add_argument("--list", action="store_true", help="list the tables")
    mode.add_argument("--print", action="store_true", help="print the generated tables (the doc is not read)")
    ap.add_argument("--fast", action="store_true", help="only the fast tables")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="only these tables")
    ap.add_argument("--ropsim", default=os.environ.get("ROPSIM", os.path.join(ROOT, "build", "ropsim")))
    ap.add_argument("--doc", default=os.path.join(ROOT, "docs", "results.md"))
    ap.add_argument("-j", "--jobs", type=int, default=2)
    ap.add_argument("--keep", action="store_true", help="keep the work folder")
    a = ap.parse_args(argv)

    if a.list:
        for name, (speed, _) in TABLES.items():
            print("%-24s %s" % (name, speed))
        return 0
    names = list(TABLES)
    if a.only:
        bad = [n for n in a.only if n not in TABLES]
        if bad:
            ap.error("unknown table(s): %s (see --list)" % ", ".join(bad))
        names = a.only
    if a.fast:
        names = [n for n in names if TABLES[n][0] == "fast"]

    text = ""
    if not a.print:
        with open(a.doc) as f:
            text = f.read()
    committed = {m.group(1): m.group(2) for m in MARK_RE.finditer(text)}
    missing = [n for n in names if n not in committed and not a.print]
    if missing:
        print("results.py: %s: no <!-- results:NAME --> ... <!-- /results:NAME --> block for: %s" % (
            a.doc, ", ".join(missing)), file=sys.stderr)
        return 1
    if not os.access(a.ropsim, os.X_OK):
        print("results.py: no ropsim binary at %s (build it, or pass --ropsim PATH)" % a.ropsim, file=sys.stderr)
        return 1

    work = tempfile.mkdtemp(prefix="ropsim-results-")
    ctx = Context(os.path.abspath(a.ropsim), a.jobs, work)
    generated = {}

    def make(n):
        t0 = time.time()
        text = TABLES[n][1](ctx)
        print("results.py: %s (%s): %.1f s" % (n, TABLES[n][0], time.time() - t0), file=sys.stderr)
        return text

    try:
        # two tables at a time (each runs up to -j ropsim processes): the text of
        # each depends only on its own runs, so the order does not matter
        with concurrent.futures.ThreadPoolExecutor(2) as ex:
            for n, text in zip(names, ex.map(make, names)):
                generated[n] = text
    finally:
        if a.keep:
            print("results.py: work folder kept: %s" % work, file=sys.stderr)
        else:
            shutil.rmtree(work, True)

    if a.print:
        for n in names:
            print("<!-- results:%s -->\n%s<!-- /results:%s -->\n" % (n, generated[n], n))
        return 0
    differ = [n for n in names if generated[n] != committed[n]]
    if a.check:
        for n in differ:
            sys.stdout.writelines(difflib.unified_diff(
                committed[n].splitlines(True), generated[n].splitlines(True),
                "%s: table %s (committed)" % (a.doc, n), "table %s (generated by the code)" % n))
        if differ:
            print("results.py: %d table(s) differ from what the code gives: %s (rewrite them with "
                  "scripts/results.py --write --only %s)" % (len(differ), ", ".join(differ), " ".join(differ)))
            return 1
        print("results.py: %d table(s) match the code: %s" % (len(names), ", ".join(names)))
        return 0

    def repl(m):
        n = m.group(1)
        body = generated.get(n, m.group(2))
        return MARK_OPEN % n + "\n" + body + MARK_CLOSE % n + "\n"

    new = MARK_RE.sub(repl, text)
    if new != text:
        tmp = a.doc + ".tmp"
        with open(tmp, "w") as f:
            f.write(new)
        os.replace(tmp, a.doc)
    print("results.py: rewrote %d table(s), %d changed: %s" % (len(names), len(differ), ", ".join(differ) or "none"))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
