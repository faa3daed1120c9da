#!/usr/bin/python3
"""The speed/accuracy trade of ropsim's fidelities, from a study of them
(studies/fidelity.toml): per (input, design), each timed fidelity's error
against the full cycle model in total cycles, DRAM bytes and the named
bottleneck, whether the sampled 95 % intervals cover the truth, and each
fidelity's host time and fragments per host second.

usage: fidelity.py STUDY_DIR [--markdown OUT.md] [--plot OUT.png] [--json OUT.json]
Runs on /usr/bin/python3 with Debian's python3-pandas and python3-matplotlib.
Exit status 1 when the study holds no cycle point to compare against.
"""
import json
import math
import os
import sqlite3
import sys

import pandas as pd


def bottleneck_class(text):
    """The bottleneck's class: the text before the first ':' (throughput
    (UNIT), bandwidth (dram) or latency; docs/reports.md "The bottleneck")."""
    return str(text).split(":")[0].strip() if isinstance(text, str) else None


def load(study_dir):
    db = sqlite3.connect(os.path.join(study_dir, "results.db"))
    df = pd.read_sql_query("SELECT * FROM results WHERE status = 'ok'", db)
    db.close()
    rows = []
    for _, r in df.iterrows():
        rep = json.loads(r["report"])
        t = rep.get("timing", {})
        host = rep.get("host", {})
        d = t.get("dram", {})
        row = {
            "input": r["input"],
            "fidelity": r.get("fidelity") or "functional",
            "design": os.path.splitext(os.path.basename(r["design"]))[0] if isinstance(r.get("design"), str) else "",
            "fragments": rep["counters"]["fragments"],
            "wall_s": host.get("wall_seconds"),
            "cycles": t.get("total_cycles"),
            "bytes": (d.get("bytes_read", 0) + d.get("bytes_written", 0)) if d else None,
            "bottleneck": bottleneck_class(t.get("bottleneck")),
        }
        if row["fidelity"] == "sampled":
            lo_c, hi_c = t["total_cycles_ci95"]
            row["cycles_lo"], row["cycles_hi"] = lo_c, hi_c
            row["read_lo"], row["read_hi"] = d["bytes_read_ci95"]
            row["written_lo"], row["written_hi"] = d["bytes_written_ci95"]
            row["bytes_read"], row["bytes_written"] = d["bytes_read"], d["bytes_written"]
            row["units_s"] = host.get("sampled_seconds")
            row["library_s"] = host.get("library_seconds")
            row["detailed"] = t["sampling"]["fragments_detailed"]
        if row["fidelity"] == "cycle":
            row["bytes_read"], row["bytes_written"] = d["bytes_read"], d["bytes_written"]
        rows.append(row)
    return pd.DataFrame(rows)


def compare(df):
    """One row per (input, design, timed fidelity other than cycle), against the cycle point."""
    cyc = df[df.fidelity == "cycle"].set_index(["input", "design"])
    func = df[df.fidelity == "functional"].set_index("input")
    out = []
    for _, r in df[~df.fidelity.isin(["cycle", "functional"])].iterrows():
        key = (r["input"], r["design"])
        if key not in cyc.index:
            continue
        c = cyc.loc[key]
        o = {
            "input": r["input"],
            "design": r["design"],
            "fidelity": r["fidelity"],
            "fragments": r["fragments"],
            "host_s": r["wall_s"],
            "cycle_host_s": c["wall_s"],
            "functional_host_s": func.loc[r["input"], "wall_s"] if r["input"] in func.index else math.nan,
            "cycles_err_pct": 100.0 * (r["cycles"] - c["cycles"]) / c["cycles"],
            "bytes_err_pct": 100.0 * (r["bytes"] - c["bytes"]) / c["bytes"] if c["bytes"] else math.nan,
            "bottleneck_ok": r["bottleneck"] == c["bottleneck"],
            "bottleneck": r["bottleneck"],
            "cycle_bottleneck": c["bottleneck"],
        }
        if r["fidelity"] == "sampled":
            o["host_s"] = r["units_s"]  # per design: the units; the library is shared (below)
            o["library_s"] = r["library_s"]
            o["covers_cycles"] = r["cycles_lo"] <= c["cycles"] <= r["cycles_hi"]
            o["covers_read"] = r["read_lo"] <= c["bytes_read"] <= r["read_hi"]
            o["covers_written"] = r["written_lo"] <= c["bytes_written"] <= r["written_hi"]
            o["detailed_share"] = r["detailed"] / r["fragments"]
        out.append(o)
    res = pd.DataFrame(out)
    if res.empty:
        return res
    # The sampled library's cost: recorded once per input (the largest
    # library_seconds of its points), shared by its designs.
    if "library_s" in res:
        lib = res[res.fidelity == "sampled"].groupby("input")["library_s"].max()
        n_designs = res[res.fidelity == "sampled"].groupby("input")["design"].nunique()
        res["host_with_library_s"] = res.apply(
            lambda r: r["host_s"] + lib[r["input"]] / n_designs[r["input"]] if r["fidelity"] == "sampled" else r["host_s"],
            axis=1,
        )
    else:
        res["host_with_library_s"] = res["host_s"]
    return res


def summary(df, res):
    """Per fidelity: speed, errors, bottleneck agreement, coverage."""
    s = []
    cyc = df[df.fidelity == "cycle"]
    func = df[df.fidelity == "functional"]
    s.append({
        "fidelity": "functional",
        "fragments_per_host_s": func.fragments.sum() / func.wall_s.sum(),
        "speedup_vs_cycle": (cyc.wall_s.sum() / 3.0) / func.wall_s.sum() if len(func) else math.nan,
    })
    s.append({"fidelity": "cycle", "fragments_per_host_s": cyc.fragments.sum() / cyc.wall_s.sum(), "speedup_vs_cycle": 1.0,
              "cycles_mae_pct": 0.0, "bytes_mae_pct": 0.0, "bottleneck_agreement": 1.0})
    for f, g in res.groupby("fidelity"):
        e = {
            "fidelity": f,
            "pairs": len(g),
            "fragments_per_host_s": g.fragments.sum() / g.host_s.sum(),
            "speedup_vs_cycle": g.cycle_host_s.sum() / g.host_s.sum(),
            "speedup_with_library": g.cycle_host_s.sum() / g.host_with_library_s.sum(),
            "cycles_mae_pct": g.cycles_err_pct.abs().mean(),
            "cycles_max_pct": g.cycles_err_pct.abs().max(),
            "bytes_mae_pct": g.bytes_err_pct.abs().mean(),
            "bytes_max_pct": g.bytes_err_pct.abs().max(),
            "bottleneck_agreement": float(g.bottleneck_ok.astype(bool).mean()),
        }
        if f == "sampled":
            c, r, w = (g[k].astype(bool) for k in ("covers_cycles", "covers_read", "covers_written"))
            e["coverage_cycles"] = float(c.mean())
            e["coverage_read"] = float(r.mean())
            e["coverage_written"] = float(w.mean())
            e["coverage_all"] = float((c & r & w).mean())
            e["pairs_whole"] = int((g.detailed_share >= 1.0).sum())
        s.append(e)
    return pd.DataFrame(s)


def fmt(v, spec):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return format(v, spec)


def markdown(res, summ):
    def pct(v):
        t = fmt(v, ".2f")
        return t + " %" if t else ""

    def times(v):
        t = fmt(v, ".1f")
        return t + "x less" if t else ""

    lines = ["| fidelity | pairs | fragments / host s | host time vs cycle | with the library | total cycles: mean abs error | max | DRAM bytes: mean abs error | max | bottleneck as cycle's | 95 % intervals cover (cycles, read, written) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for _, r in summ.iterrows():
        cov = ""
        if r["fidelity"] == "sampled":
            cov = f"{r['coverage_cycles']:.0%}, {r['coverage_read']:.0%}, {r['coverage_written']:.0%}"
            if r.get("pairs_whole", 0):
                cov += f" ({r['pairs_whole']:.0f} pairs simulated whole)"
        lines.append(
            f"| {r['fidelity']} | {fmt(r.get('pairs'), '.0f')} | {fmt(r['fragments_per_host_s'] / 1e6, '.2f')} M "
            f"| {times(r['speedup_vs_cycle'])} | {times(r.get('speedup_with_library'))} "
            f"| {pct(r.get('cycles_mae_pct'))} | {pct(r.get('cycles_max_pct'))} | {pct(r.get('bytes_mae_pct'))} "
            f"| {pct(r.get('bytes_max_pct'))} | {fmt(r.get('bottleneck_agreement'), '.0%')} | {cov} |")
    lines.append("")
    lines.append("| input | design | fidelity | host s | cycle host s | total cycles error | DRAM bytes error | bottleneck (cycle's) | interval covers |")
    lines.append("|---|---|---|---:|---:|---:|---:|---|---|")
    for _, r in res.sort_values(["input", "design", "fidelity"]).iterrows():
        cov = ""
        if r["fidelity"] == "sampled":
            cov = "/".join("yes" if r[k] else "no" for k in ("covers_cycles", "covers_read", "covers_written"))
        b = r["bottleneck"] if r["bottleneck_ok"] else f"{r['bottleneck']} ({r['cycle_bottleneck']})"
        lines.append(f"| {r['input']} | {r['design']} | {r['fidelity']} | {r['host_s']:.3f} | {r['cycle_host_s']:.3f} "
                     f"| {r['cycles_err_pct']:+.2f} % | {r['bytes_err_pct']:+.2f} % | {b} | {cov} |")
    return "\n".join(lines) + "\n"


def plot(res, summ, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=110)
    colors = {"approximate": "tab:orange", "sampled": "tab:blue"}
    for f, g in res.groupby("fidelity"):
        ax.scatter(g.cycle_host_s / g.host_s, g.cycles_err_pct.abs(), s=18, alpha=0.5, color=colors.get(f, "gray"),
                   label=f"{f}: each (input, design)")
    for _, r in summ.iterrows():
        if r["fidelity"] in colors:
            ax.scatter([r["speedup_vs_cycle"]], [r["cycles_mae_pct"]], s=120, marker="*",
                       color=colors[r["fidelity"]], edgecolor="black", label=f"{r['fidelity']}: mean")
    ax.scatter([1.0], [0.0], s=80, marker="s", color="black", label="cycle (the truth)")
    f = summ[summ.fidelity == "functional"]
    if len(f) and not math.isnan(f.iloc[0]["speedup_vs_cycle"]):
        ax.axvline(f.iloc[0]["speedup_vs_cycle"], ls=":", color="gray", label="functional: the image, no time")
    ax.set_xscale("log")
    ax.set_xlabel("host time, cycle model / this fidelity (per design)")
    ax.set_ylabel("|error| in total cycles (%)")
    ax.set_title("ropsim fidelities: speed against error (lk, 16 spp)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    tmp = out + ".tmp.png"
    fig.savefig(tmp)
    os.replace(tmp, out)


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    study = argv[1]
    opts = dict(zip(argv[2::2], argv[3::2]))
    df = load(study)
    if not (df.fidelity == "cycle").any():
        print(f"{study}: no cycle point to compare against", file=sys.stderr)
        return 1
    res = compare(df)
    summ = summary(df, res)
    md = markdown(res, summ)
    if "--markdown" in opts:
        with open(opts["--markdown"] + ".tmp", "w") as f:
            f.write(md)
        os.replace(opts["--markdown"] + ".tmp", opts["--markdown"])
    else:
        sys.stdout.write(md)
    if "--plot" in opts:
        plot(res, summ, opts["--plot"])
    if "--json" in opts:
        with open(opts["--json"] + ".tmp", "w") as f:
            json.dump({"summary": json.loads(summ.to_json(orient="records")),
                       "pairs": json.loads(res.to_json(orient="records"))}, f, indent=1)
        os.replace(opts["--json"] + ".tmp", opts["--json"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
