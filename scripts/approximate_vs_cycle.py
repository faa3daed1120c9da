#!/usr/bin/python3
"""The analytical model against the cycle model (docs/results.md "The
analytical model with compression and Hi-Z"): cloth, smoke and testcard at 16 spp and traces (the motor:
`ropsim capture traces/scenes/mesh/motor.toml -o motor.rtr`) on the three
designs. Prints a Markdown table -- total cycles of both, the error, DRAM
bytes read, written and both (the approximate model's error), the bottleneck of
both, the wall time of the functional, approximate and cycle runs -- and the
mean absolute error in total cycles.

    scripts/approximate_vs_cycle.py [--build build] [--trace motor.rtr] [--scenes cloth,smoke,testcard]
        [--designs default,narrow,wide] [--spp 16] [--method lk] [--no-header]
"""
import argparse
import atexit
import json
import os
import shutil
import subprocess
import tempfile
import time

root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ap = argparse.ArgumentParser()
ap.add_argument("--build", default=os.path.join(root, "build"))
ap.add_argument("--trace", action="append", default=[], help="a trace file (repeatable)")
ap.add_argument("--scenes", default="cloth,smoke,testcard")
ap.add_argument("--designs", default="default,narrow,wide")
ap.add_argument("--spp", default="16", help="samples per pixel of the scenes")
ap.add_argument("--method", default="lk")
ap.add_argument("--no-header", action="store_true")
a = ap.parse_args()
ropsim = os.path.join(a.build, "ropsim")
work = tempfile.mkdtemp(prefix="ropsim-approx-")
atexit.register(shutil.rmtree, work, True)


def run(args, name):
    t0 = time.time()
    subprocess.run([ropsim, "run", *args, "--quiet", "--out", f"{work}/{name}.png", "--report", f"{work}/{name}.json"],
                   check=True)
    return time.time() - t0, json.load(open(f"{work}/{name}.json"))


def pct(x, y):
    return 0.0 if x == y == 0 else 100.0 * (x / y - 1)


def kind(b):  # "bandwidth (dram): bound ..." -> "bandwidth (dram)"
    return b.split(":")[0]


inputs = [(f"{s} {a.spp} spp", ["--scene", s, "--spp", a.spp]) for s in a.scenes.split(",") if s]
inputs += [(os.path.basename(t), ["--trace", t]) for t in a.trace]
if not a.no_header:
    print("| input | design | cycle total | approximate | error | DRAM read | DRAM written | DRAM bytes "
          "| bottleneck (cycle; same?) | host s: functional / approximate / cycle |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---|---|")
errs, byte_errs = [], []
for label, inp in inputs:
    inp = [*inp, "--method", a.method]
    if a.method != "lk":
        label += " " + a.method
    for d in a.designs.split(","):
        hw = ["--hw", os.path.join(root, "configs", d + ".toml")]
        # The design's numerics and render-target formats are the functional run's too.
        tf, _ = run([*inp, "--fidelity", "functional", *hw], "f")
        golden = open(f"{work}/f.png", "rb").read()
        tc, c = run([*inp, "--fidelity", "cycle", *hw], "c")
        ta, x = run([*inp, "--fidelity", "approximate", *hw], "a")
        assert open(f"{work}/a.png", "rb").read() == golden, "the approximate image is not the golden image"
        c, x = c["timing"], x["timing"]
        e = pct(x["total_cycles"], c["total_cycles"])
        errs.append(abs(e))
        total = [d["bytes_read"] + d["bytes_written"] for d in (x["dram"], c["dram"])]
        byte_errs.append(abs(pct(*total)))
        same = "yes" if kind(c["bottleneck"]) == kind(x["bottleneck"]) else "no: " + kind(x["bottleneck"])
        print(f"| {label} | {d} | {c['total_cycles']:,} | {x['total_cycles']:,} | {e:+.1f} % "
              f"| {pct(x['dram']['bytes_read'], c['dram']['bytes_read']):+.2f} % "
              f"| {pct(x['dram']['bytes_written'], c['dram']['bytes_written']):+.2f} % "
              f"| {pct(*total):+.2f} % "
              f"| {kind(c['bottleneck'])}; {same} | {tf:.2f} / {ta:.2f} / {tc:.2f} |", flush=True)
print(f"\nmean absolute error in total cycles: {sum(errs) / len(errs):.1f} % over {len(errs)} pairs "
      f"(largest {max(errs):.1f} %); in DRAM bytes (read + written): {sum(byte_errs) / len(byte_errs):.2f} % "
      f"(largest {max(byte_errs):.2f} %)")
