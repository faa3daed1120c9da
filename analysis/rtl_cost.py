#!/usr/bin/python3
"""Silicon cost of the reference RTL from the Yosys sweep (scripts/synth.sh
--set sweep): a markdown table of every run and a two-panel plot, area
(NAND2 equivalents) against samples per pixel and against hash bits.

usage: rtl_cost.py SWEEP.csv [--markdown OUT.md] [--plot OUT.png]
Runs on /usr/bin/python3 with Debian's python3-pandas and python3-matplotlib.
Exit status 1 when the CSV holds no run.
"""
import sys

import pandas as pd

NAMES = {
    "rop_alpha_ref": "alpha-ref generator",
    "rop_opacity_test": "opacity test",
    "rop_tracker_update": "tracker update",
    "rop_depth_compare": "depth compare",
    "rop_hilbert_index": "Hilbert index",
    "rop_bitonic_sorter": "bitonic sorter",
}


def load(path):
    df = pd.read_csv(path)
    params = df["params"].apply(lambda s: dict(kv.split("=") for kv in s.split()))
    for key in sorted({k for p in params for k in p}):
        df[key] = params.apply(lambda p, k=key: int(p[k]) if k in p else None)
    df["unit"] = df["module"].map(NAMES)
    return df


def markdown(df):
    lines = [
        "| unit | parameters | cells | flip-flops | transistors | NAND2 eq. | levels (deepest stage) |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for _, r in df.iterrows():
        lines.append(
            f"| {r['unit']} | {r['params']} | {r['cells']} | {r['flipflops']} | {r['transistors']} "
            f"| {r['nand2_eq']} | {r['levels']} |"
        )
    return "\n".join(lines) + "\n"


def plot(df, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    # The sweep also holds other widths and stage counts (the cost model's
    # checks, docs/rtl.md): each curve keeps the runs of its fixed parameters.
    by_spp = [
        ("rop_bitonic_sorter", "N", {}, "bitonic sorter (N = spp)"),
        ("rop_tracker_update", "SPP", {"SID_BITS": 32, "STAGES": 1}, "tracker update"),
        ("rop_depth_compare", "LANES", {"STAGES": 2}, "depth compare (spp lanes)"),
        ("rop_opacity_test", "LANES", {"HASH_BITS": 32, "ALPHA_BITS": 32, "STAGES": 1},
         "opacity test (spp lanes, 32-bit ref)"),
    ]
    for module, x, fixed, label in by_spp:
        d = df[df["module"] == module]
        for k, v in fixed.items():
            d = d[d[k] == v]
        d = d.sort_values(x)
        if len(d):
            a.plot(d[x], d["nand2_eq"], "o-", label=label)
    a.set_xscale("log", base=2)
    a.set_yscale("log")
    a.set_xlabel("samples per pixel")
    a.set_ylabel("NAND2 equivalents (transistors / 4)")
    a.set_title("area against spp")
    a.legend(fontsize=8)
    a.grid(True, which="both", alpha=0.3)
    for lanes in sorted(df[df["module"] == "rop_alpha_ref"]["LANES"].dropna().unique()):
        d = df[(df["module"] == "rop_alpha_ref") & (df["LANES"] == lanes) & (df["STAGES"] == 4)
               & (df["SID_BITS"] == 32)].sort_values("HASH_BITS")
        if len(d) > 1:
            b.plot(d["HASH_BITS"], d["nand2_eq"], "o-", label=f"alpha-ref, {int(lanes)} lane(s), 4 stages")
    d = df[(df["module"] == "rop_opacity_test") & (df["LANES"] == 16) & (df["ALPHA_BITS"] == 32)
           & (df["STAGES"] == 1)].sort_values("HASH_BITS")
    if len(d):
        b.plot(d["HASH_BITS"], d["nand2_eq"], "s--", label="opacity test, 16 lanes")
    b.set_yscale("log")
    b.set_xlabel("hash bits")
    b.set_ylabel("NAND2 equivalents")
    b.set_title("area against hash width")
    b.legend(fontsize=8)
    b.grid(True, which="both", alpha=0.3)
    fig.suptitle("Yosys generic synthesis (abc -g cmos2), stat -tech cmos; no wires, no library timing", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip(), file=sys.stderr)
        return 1
    df = load(argv[1])
    if df.empty:
        print(f"{argv[1]}: no synthesis run", file=sys.stderr)
        return 1
    args = argv[2:]
    md_out = args[args.index("--markdown") + 1] if "--markdown" in args else None
    png_out = args[args.index("--plot") + 1] if "--plot" in args else None
    text = markdown(df)
    if md_out:
        with open(md_out, "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    if png_out:
        plot(df, png_out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
