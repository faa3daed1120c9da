#!/usr/bin/python3
"""The speed/accuracy trade of ropsim's fidelities, from a study of them
(studies/fidelity.toml): per (input, design), each timed fidelity's error
against the full cycle model in total cycles, DRAM bytes and the named
bottleneck, whether the sampled 95 % intervals cover the truth, and each
fidelity's host time and fragments per host second.

usage: fidelity.py STUDY_DIR [--markdown OUT.md] [--plot OUT.png] [--json OUT.json]
Runs on /usr/bin/python3 with Debian's python3-pandas and python3-matplotlib.
Exit status 1 when the study holds no cycle point to compare against.

The study's report (`ropsim study report`, docs/studies.md "The report") has
the same comparison point by point in its section "Fidelities"; its
per-point rows come from points() and compare() here.
"""
import json
import math
import os
import sqlite3
import sys

import pandas as pd

# The parameters that never tell two points of a comparison apart: the
# fidelity is what is compared, and a seed is averaged over.
NOT_KEYS = ("fidelity", "seed")


def bottleneck_class(text):
    """The bottleneck's class: the text before the first ':' (throughput
    (UNIT), bandwidth (dram) or latency; docs/reports.md "The bottleneck")."""
    return str(text).split(":")[0].strip() if isinstance(text, str) and text else None


def design_name(v):
    """A design file's stem ("" for a point without a design: functional)."""
    return os.path.splitext(os.path.basename(v))[0] if isinstance(v, str) and v else ""


def _pair(v):
    return (float(v[0]), float(v[1])) if isinstance(v, (list, tuple)) and len(v) == 2 else (math.nan, math.nan)


def points(results):
    """One row per ok point of a results table (the study's results.db) with
    what the comparison needs, from its report: fidelity, fragments, host
    seconds, total cycles, DRAM bytes read and written, their 95 % intervals
    (sampled points; NaN otherwise), the bottleneck's class."""
    rows = []
    for i, r in results[results["status"] == "ok"].iterrows():
        try:
            rep = json.loads(r["report"]) if isinstance(r.get("report"), str) else {}
        except ValueError:
            rep = {}
        t, host = rep.get("timing") or {}, rep.get("host") or {}
        d = t.get("dram") or {}
        fidelity = r.get("fidelity") if isinstance(r.get("fidelity"), str) else "functional"
        timed = "total_cycles" in t
        row = {
            "row": i,
            "point": r.get("point"),
            "fidelity": fidelity,
            "fragments": float((rep.get("counters") or {}).get("fragments", math.nan)),
            "wall_s": float(host.get("wall_seconds", math.nan)),
            "cycles": float(t["total_cycles"]) if timed else math.nan,
            "frame_us": float(t.get("frame_time_us", math.nan)) if timed else math.nan,
            "bytes_read": float(d.get("bytes_read", math.nan)),
            "bytes_written": float(d.get("bytes_written", math.nan)),
            "bottleneck": bottleneck_class(t.get("bottleneck")),
            "units_s": float(host.get("sampled_seconds", math.nan)),
            "library_s": float(host.get("library_seconds", math.nan)),
        }
        row["bytes"] = row["bytes_read"] + row["bytes_written"]
        row["cycles_lo"], row["cycles_hi"] = _pair(t.get("total_cycles_ci95"))
        row["read_lo"], row["read_hi"] = _pair(d.get("bytes_read_ci95"))
        row["written_lo"], row["written_hi"] = _pair(d.get("bytes_written_ci95"))
        sampling = t.get("sampling") or {}
        row["detailed"] = float(sampling.get("fragments_detailed", math.nan))
        rows.append(row)
    return pd.DataFrame(rows, columns=["row", "point", "fidelity", "fragments", "wall_s", "cycles", "frame_us",
                                       "bytes_read", "bytes_written", "bottleneck", "units_s", "library_s", "bytes",
                                       "cycles_lo", "cycles_hi", "read_lo", "read_hi", "written_lo", "written_hi",
                                       "detailed"])


def _pct(est, truth):
    return 100.0 * (est - truth) / truth if truth and not math.isnan(truth) and not math.isnan(est) else math.nan


def _within(lo, v, hi):
    """Whether v lies in [lo, hi]; None without an interval."""
    return None if math.isnan(lo) or math.isnan(hi) else bool(lo <= v <= hi)


def compare(results, keys):
    """One row per ok point that is not a cycle point, against the cycle
    points that agree with it on every parameter of keys the point has (a
    functional point has no design: every design's cycle point of its input):
    the point's estimates, their errors against the cycle model in % (cycle
    values averaged when several match), whether each cycle value lies in the
    point's 95 % interval, the bottleneck against the cycle model's, and the
    host time beside the cycle points' mean. results: the results table,
    keys: its columns that name a comparison (input, design, ...)."""
    pts = points(results)
    if pts.empty:
        return pd.DataFrame()
    par = results.loc[pts["row"], list(keys)].reset_index(drop=True)
    pts = pd.concat([pts.reset_index(drop=True), par], axis=1)
    cyc = pts[pts["fidelity"] == "cycle"]
    out = []
    for _, r in pts[pts["fidelity"] != "cycle"].iterrows():
        m = cyc
        for k in keys:
            if not pd.isna(r[k]):
                m = m[m[k] == r[k]]
        if m.empty:
            continue
        o = {k: r[k] for k in keys}
        o.update(point=r["point"], fidelity=r["fidelity"], fragments=r["fragments"], host_s=r["wall_s"],
                 cycle_host_s=float(m["wall_s"].mean()), cycle_points=len(m), cycles=r["cycles"],
                 cycles_lo=r["cycles_lo"], cycles_hi=r["cycles_hi"], frame_us=r["frame_us"], bytes=r["bytes"],
                 cycle_cycles=float(m["cycles"].mean()), cycle_bytes=float(m["bytes"].mean()),
                 cycle_frame_us=float(m["frame_us"].mean()), bottleneck=r["bottleneck"],
                 units_s=r["units_s"], library_s=r["library_s"], detailed=r["detailed"])
        o["speedup"] = o["cycle_host_s"] / o["host_s"] if o["host_s"] > 0 else math.nan
        o["cycles_err_pct"] = _pct(r["cycles"], o["cycle_cycles"])
        o["bytes_err_pct"] = _pct(r["bytes"], o["cycle_bytes"])
        o["cycle_read"], o["cycle_written"] = float(m["bytes_read"].mean()), float(m["bytes_written"].mean())
        o["read_lo"], o["read_hi"] = r["read_lo"], r["read_hi"]
        o["written_lo"], o["written_hi"] = r["written_lo"], r["written_hi"]
        o["read_err_pct"] = _pct(r["bytes_read"], o["cycle_read"])
        o["written_err_pct"] = _pct(r["bytes_written"], o["cycle_written"])
        single = len(m) == 1
        c = m.iloc[0]
        o["covers_cycles"] = _within(r["cycles_lo"], c["cycles"], r["cycles_hi"]) if single else None
        o["covers_read"] = _within(r["read_lo"], c["bytes_read"], r["read_hi"]) if single else None
        o["covers_written"] = _within(r["written_lo"], c["bytes_written"], r["written_hi"]) if single else None
        timed = not math.isnan(r["cycles"])
        o["cycle_bottleneck"] = c["bottleneck"] if single else None
        o["bottleneck_ok"] = (r["bottleneck"] == c["bottleneck"]) if timed and single else None
        out.append(o)
    return pd.DataFrame(out)


def study_pairs(study_dir):
    """compare() over a study folder's results.db by (input, design)."""
    db = sqlite3.connect(os.path.join(study_dir, "results.db"))
    try:
        df = pd.read_sql_query("SELECT * FROM results", db)
    finally:
        db.close()
    if "design" not in df.columns:
        df["design"] = None
    df["design"] = [design_name(v) if isinstance(v, str) else None for v in df["design"]]
    pts = points(df)
    res = compare(df, ["input", "design"])
    if res.empty:
        return pts, res
    # The sampled points' host time: the units' (host.sampled_seconds), and
    # with the library its recording (the largest library_seconds of the
    # input's sampled points) shared by the input's designs.
    smp = res["fidelity"] == "sampled"
    res.loc[smp, "host_s"] = res.loc[smp, "units_s"]
    lib = res[smp].groupby("input")["library_s"].max()
    n_designs = res[smp].groupby("input")["design"].nunique()
    res["host_with_library_s"] = [
        r["host_s"] + lib[r["input"]] / n_designs[r["input"]] if r["fidelity"] == "sampled" else r["host_s"]
        for _, r in res.iterrows()
    ]
    res["speedup"] = res["cycle_host_s"] / res["host_s"]
    return pts.assign(input=df.loc[pts["row"], "input"].to_numpy()), res


def _ratio(num, den):
    return num / den if den > 0 else math.nan


def summary(pts, res):
    """Per fidelity: speed against the cycle model, errors, bottleneck
    agreement, interval coverage. The cycle model is the reference (its
    errors are 0 by definition, its speed-up 1); a functional point has no
    timing, so only its speed."""
    s = []
    cyc = pts[pts["fidelity"] == "cycle"]
    s.append({"fidelity": "cycle", "pairs": len(cyc), "reference": True,
              "fragments_per_host_s": _ratio(cyc["fragments"].sum(), cyc["wall_s"].sum()), "speedup_vs_cycle": 1.0})
    if res.empty:
        return pd.DataFrame(s)
    for f, g in res.groupby("fidelity", sort=False):
        e = {
            "fidelity": f,
            "pairs": len(g),
            "fragments_per_host_s": _ratio(g["fragments"].sum(), g["host_s"].sum()),
            # Each cycle point once: a functional point is compared with several.
            "speedup_vs_cycle": _ratio((g["cycle_host_s"] * g["cycle_points"]).sum(),
                                       (g["host_s"] * g["cycle_points"]).sum()),
        }
        if "host_with_library_s" in g and f == "sampled":
            e["speedup_with_library"] = _ratio(g["cycle_host_s"].sum(), g["host_with_library_s"].sum())
        timed = g[g["cycles"].notna()]
        if not timed.empty:
            e.update(cycles_mae_pct=float(timed["cycles_err_pct"].abs().mean()),
                     cycles_max_pct=float(timed["cycles_err_pct"].abs().max()),
                     bytes_mae_pct=float(timed["bytes_err_pct"].abs().mean()),
                     bytes_max_pct=float(timed["bytes_err_pct"].abs().max()),
                     bottleneck_agreement=float(timed["bottleneck_ok"].dropna().astype(bool).mean()))
        cov = g[g["covers_cycles"].notna()]
        if not cov.empty:
            c, r, w = (cov[k].astype(bool) for k in ("covers_cycles", "covers_read", "covers_written"))
            e.update(coverage_cycles=float(c.mean()), coverage_read=float(r.mean()), coverage_written=float(w.mean()),
                     coverage_all=float((c & r & w).mean()),
                     pairs_whole=int((cov["detailed"] >= cov["fragments"]).sum()))
        s.append(e)
    return pd.DataFrame(s)


def fmt(v, spec):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return format(v, spec)


def times(v):
    """A speed-up: '3.2x faster', '1.4x slower'."""
    if v is None or math.isnan(v):
        return ""
    return f"{v:.1f}x faster" if v >= 1 else f"{1 / v:.1f}x slower"


def markdown(res, summ):
    def pct(v):
        t = fmt(v, ".2f")
        return t + " %" if t else ""

    lines = ["| fidelity | pairs | fragments / host s | speed against cycle | with the library | total cycles: mean abs "
             "error | max | DRAM bytes: mean abs error | max | bottleneck as cycle's | 95 % intervals cover (cycles, "
             "read, written) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for _, r in summ.iterrows():
        f = r["fidelity"]
        rate = fmt(r["fragments_per_host_s"] / 1e6, ".2f")
        if r.get("reference") is True:
            lines.append(f"| cycle | {r['pairs']:.0f} | {rate} M | the reference | | 0 (the reference) | | "
                         "0 (the reference) | | | |")
            continue
        cov = ""
        if not pd.isna(r.get("coverage_cycles", math.nan)):
            cov = f"{r['coverage_cycles']:.0%}, {r['coverage_read']:.0%}, {r['coverage_written']:.0%}"
            if r.get("pairs_whole", 0):
                cov += f" ({r['pairs_whole']:.0f} pairs simulated whole)"
        if pd.isna(r.get("cycles_mae_pct", math.nan)):
            errs = "no timing | | no timing | | |"
        else:
            errs = (f"{pct(r['cycles_mae_pct'])} | {pct(r['cycles_max_pct'])} | {pct(r['bytes_mae_pct'])} "
                    f"| {pct(r['bytes_max_pct'])} | {fmt(r['bottleneck_agreement'], '.0%')} |")
        lines.append(f"| {f} | {r['pairs']:.0f} | {rate} M | {times(r['speedup_vs_cycle'])} "
                     f"| {times(r.get('speedup_with_library', math.nan))} | {errs} {cov} |")
    lines.append("")
    lines.append("| input | design | fidelity | host s | cycle host s | total cycles error | DRAM bytes error | "
                 "bottleneck (cycle's) | interval covers |")
    lines.append("|---|---|---|---:|---:|---:|---:|---|---|")
    timed = res[res["cycles"].notna()] if not res.empty else res
    for _, r in timed.sort_values(["input", "design", "fidelity"]).iterrows():
        cov = ""
        if r["covers_cycles"] is not None and not pd.isna(r["covers_cycles"]):
            cov = "/".join("yes" if r[k] else "no" for k in ("covers_cycles", "covers_read", "covers_written"))
        b = r["bottleneck"] if r["bottleneck_ok"] else f"{r['bottleneck']} ({r['cycle_bottleneck']})"
        lines.append(f"| {r['input']} | {r['design']} | {r['fidelity']} | {r['host_s']:.3f} | {r['cycle_host_s']:.3f} "
                     f"| {r['cycles_err_pct']:+.2f} % | {r['bytes_err_pct']:+.2f} % | {b} | {cov} |")
    return "\n".join(lines) + "\n"


def plot(res, summ, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.4, 4.6), dpi=110, layout="constrained")
    colors = {"approximate": "tab:orange", "sampled": "tab:blue"}
    timed = res[res["cycles"].notna()]
    for f, g in timed.groupby("fidelity"):
        ax.scatter(g["speedup"], g["cycles_err_pct"].abs(), s=18, alpha=0.5, color=colors.get(f, "gray"),
                   label=f"{f}: each (input, design)")
    for _, r in summ.iterrows():
        if r["fidelity"] in colors and not pd.isna(r.get("cycles_mae_pct", math.nan)):
            ax.scatter([r["speedup_vs_cycle"]], [r["cycles_mae_pct"]], s=120, marker="*",
                       color=colors[r["fidelity"]], edgecolor="black", label=f"{r['fidelity']}: mean")
    ax.scatter([1.0], [0.0], s=80, marker="s", color="black", label="cycle (the reference)")
    f = summ[summ["fidelity"] == "functional"]
    if len(f) and not math.isnan(f.iloc[0]["speedup_vs_cycle"]):
        ax.axvline(f.iloc[0]["speedup_vs_cycle"], ls=":", color="gray", label="functional: the image, no timing")
    ax.set_xscale("log")
    ax.set_xlabel("speed-up over the cycle model (its host time / this fidelity's, per design)")
    ax.set_ylabel("|error| in total cycles (%)")
    ax.set_title("ropsim fidelities: speed against error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=9, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0)
    tmp = out + ".tmp.png"
    fig.savefig(tmp)
    os.replace(tmp, out)


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    study = argv[1]
    opts = dict(zip(argv[2::2], argv[3::2]))
    if not os.path.isfile(os.path.join(study, "results.db")):
        print(f"fidelity: error: {study}: not a study folder (no results.db)", file=sys.stderr)
        return 1
    pts, res = study_pairs(study)
    if not (pts["fidelity"] == "cycle").any() if not pts.empty else True:
        print(f"fidelity: error: {study}: no cycle point to compare against", file=sys.stderr)
        return 1
    summ = summary(pts, res)
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
