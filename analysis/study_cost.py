#!/usr/bin/python3
"""Quality against a parameter against gates: a study's RMSE and bias beside
the silicon cost its points report (silicon.*, docs/rtl.md "Cost of a
design"), as a Markdown table and a three-panel plot.

usage: study_cost.py DIR --param P [--spp S] [--method M] [--markdown OUT.md] [--plot OUT.png]

DIR is a study folder (`ropsim study run`); P a swept numeric parameter (for
studies/hash-width.toml: hash_bits). Per value of P and per input: the mean
RMSE (8-bit units) over the other parameters (scene seeds) with its standard
deviation, the mean bias, and the silicon figures of the points (the same for
every seed): the alpha-reference generator's NAND2 equivalents, the LK units
of one ROP, the whole design, and whether they are sweep rows or model
estimates (with the model's bound). Runs on /usr/bin/python3 with Debian's
pandas, numpy and matplotlib. Exit status 1: not a study folder, or no point
with both an RMSE and a silicon cost.
"""
import os
import sys

import numpy as np
import pandas as pd

RMSE = "vs_reference.rmse_8bit"
BIAS = "vs_reference.bias_8bit"
ALPHA = "silicon.units.alpha_ref.nand2_eq"
ALPHA_EST = "silicon.units.alpha_ref.estimate"
ALPHA_BOUND = "silicon.units.alpha_ref.error_bound"
ALPHA_LEVELS = "silicon.units.alpha_ref.levels"
ROP = "silicon.per_rop.nand2_eq"
TOTAL = "silicon.total.nand2_eq"
ROPS = "silicon.rop_units"
REASON = "silicon.reason"


def numeric(df, col):
    if col not in df.columns:
        return pd.Series(np.nan, index=df.index, dtype=float)
    return pd.to_numeric(df[col], errors="coerce")


def kgates(v):
    return "—" if v is None or np.isnan(v) else f"{v / 1000:.1f} k"


def cost_frame(df, param, spp=None, method=None):
    """The ok points with an RMSE, grouped by (input, spp, param): RMSE mean and
    std, bias, and the silicon figures (first of the group; every seed's are
    equal). Returns (table DataFrame, reasons of points without a cost)."""
    ok = df[df["status"] == "ok"].copy()
    if spp is not None and "spp" in ok.columns:
        ok = ok[numeric(ok, "spp") == spp]
    if method is not None and "method" in ok.columns:
        ok = ok[ok["method"].astype(str) == method]
    ok["_x"] = numeric(ok, param)
    ok["_rmse"] = numeric(ok, RMSE)
    ok = ok[ok["_x"].notna() & ok["_rmse"].notna()]
    reasons = sorted({str(r) for r in ok.get(REASON, pd.Series(dtype=str)).dropna() if str(r)})
    for c in (BIAS, ALPHA, ALPHA_BOUND, ALPHA_LEVELS, ROP, TOTAL, ROPS):
        ok[c] = numeric(ok, c)
    if ALPHA_EST not in ok.columns:
        ok[ALPHA_EST] = None
    keys = [k for k in ("input", "spp") if k in ok.columns] + ["_x"]
    agg = ok.groupby(keys, dropna=False).agg(
        rmse=("_rmse", "mean"), rmse_sd=("_rmse", "std"), n=("_rmse", "size"), bias=(BIAS, "mean"),
        alpha=(ALPHA, "min"), alpha_hi=(ALPHA, "max"), alpha_est=(ALPHA_EST, lambda v: "/".join(sorted({str(x) for x in v.dropna()}))),
        alpha_bound=(ALPHA_BOUND, "first"), alpha_levels=(ALPHA_LEVELS, "min"), alpha_levels_hi=(ALPHA_LEVELS, "max"), rop=(ROP, "min"),
        rop_hi=(ROP, "max"), total=(TOTAL, "min"), total_hi=(TOTAL, "max"), rops=(ROPS, "first")).reset_index()
    return agg, reasons


def markdown(agg, param):
    """One row per value of the parameter: each input's RMSE (and bias), then
    the gates (the same for every input)."""
    head, rows = table(agg, param)
    lines = ["| " + " | ".join(head) + " |", "|" + "---:|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def table(agg, param):
    """The table's header and rows (strings)."""
    inputs = list(pd.unique(agg["input"])) if "input" in agg.columns else [None]
    spps = sorted(pd.unique(agg["spp"])) if "spp" in agg.columns and param != "spp" else [None]
    head = [param]
    for inp in inputs:
        for s in spps:
            tag = " ".join(str(v) for v in (inp, f"{int(s)} spp" if s is not None and len(spps) > 1 else None) if v)
            head += [f"{tag} RMSE", f"{tag} bias"]
    rops = agg["rops"].dropna()
    nrop = int(rops.iloc[0]) if len(rops) else None
    head += ["alpha-ref NAND2 eq.", "alpha-ref levels", "LK units, one ROP",
             f"design ({nrop} ROPs)" if nrop else "design", "alpha-ref estimate"]
    rows = []
    for x in sorted(pd.unique(agg["_x"])):
        a = agg[agg["_x"] == x]
        row = [f"{x:g}"]
        for inp in inputs:
            for s in spps:
                g = a
                if inp is not None:
                    g = g[g["input"] == inp]
                if s is not None:
                    g = g[g["spp"] == s]
                if g.empty:
                    row += ["—", "—"]
                    continue
                r = g.iloc[0]
                sd = f" ± {r['rmse_sd']:.3f}" if r["n"] > 1 and not np.isnan(r["rmse_sd"]) else ""
                row += [f"{r['rmse']:.3f}{sd}", "—" if np.isnan(r["bias"]) else f"{r['bias']:+.3f}"]
        r = a.iloc[0]
        ests = {e for v in a["alpha_est"] for e in str(v).split("/") if e}
        est = "mixed" if len(ests) > 1 else (ests.pop() if ests else "none")
        if est == "model" and not np.isnan(r["alpha_bound"]):
            est = f"model (±{100 * r['alpha_bound']:.0f} %)"
        lo, hi = a["alpha_levels"].min(), a["alpha_levels_hi"].max()
        lv = "—" if np.isnan(lo) else f"{lo:.0f}" if lo == hi else f"{lo:.0f}–{hi:.0f}"
        def span(col):
            # One figure unless the cost differs within the row: the inputs' screens (the Hilbert index's
            # order) or another swept parameter that changes it (then its range).
            lo, hi = a[col].min(), a[col + "_hi"].max()
            return kgates(lo) if lo == hi or np.isnan(lo) else f"{kgates(lo)}–{kgates(hi)}"

        row += [span("alpha"), lv, span("rop"), span("total"), est]
        rows.append(row)
    return head, rows


def plot(agg, param, out=None, title=""):
    """The three panels; written to out (and closed), else returned. Drawn
    for a page at 100 % zoom (96 dpi, 13 inches wide), the legends below the
    panels, logarithmic axes only where the values span a decade."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    def spans(v):
        v = np.asarray([x for x in v if x is not None and np.isfinite(x)], dtype=float)
        return len(v) > 1 and v.min() > 0 and v.max() / v.min() >= 10

    fig, (a, b, c) = plt.subplots(1, 3, figsize=(13, 4.9), dpi=96, layout="constrained")
    keys = [k for k in ("input", "spp") if k in agg.columns and k != param]
    groups = agg.groupby(keys if len(keys) > 1 else keys[0], sort=False) if keys else [((), agg)]
    for gk, g in groups:
        g = g.sort_values("_x")
        gk = gk if isinstance(gk, tuple) else (gk,)
        lab = " ".join(f"{v} spp" if k == "spp" else str(v) for k, v in zip(keys, gk))
        line, = a.plot(g["_x"], g["rmse"], "o-", ms=4, label=lab)
        if (g["n"] > 1).any():
            a.fill_between(g["_x"], g["rmse"] - g["rmse_sd"], g["rmse"] + g["rmse_sd"], alpha=.15,
                           color=line.get_color())
        c.plot(g["rop"], g["rmse"], "o-", ms=4, label=lab, color=line.get_color())
        for _, r in g.iterrows():
            c.annotate(f"{r['_x']:g}", (r["rop"], r["rmse"]), textcoords="offset points", xytext=(3, 3), fontsize=8)
    xs = sorted(agg["_x"].dropna().unique())
    for ax in (a, b):
        if len(xs) > 1 and xs[0] > 0 and xs[-1] / xs[0] >= 8:
            ax.set_xscale("log", base=2)
        if len(xs) <= 10:
            ax.set_xticks(xs, [f"{v:g}" for v in xs])
            ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    below = dict(loc="upper left", bbox_to_anchor=(0.0, -0.2), borderaxespad=0, frameon=False)
    a.set_xlabel(param)
    a.set_ylabel("RMSE (8-bit units), mean ± sd")
    a.set_title(f"quality against {param}")
    a.grid(alpha=.3)
    a.legend(**below)
    g = agg.drop_duplicates("_x").sort_values("_x")
    sweep = g["alpha_est"] == "sweep"
    bound = g["alpha_bound"].fillna(0)
    for col, lab, mk, colour in (("alpha", "alpha-ref generator", "o", "C0"), ("rop", "LK units of one ROP", "s", "C3")):
        b.plot(g["_x"], g[col], "-", color=colour, lw=1, alpha=.5)
        b.plot(g["_x"][sweep], g[col][sweep], mk, ms=6, color=colour, label=f"{lab} (sweep row)")
        # model points with the alpha-ref model's bound (the rest of the ROP is sweep rows)
        err = bound[~sweep] * g["alpha"][~sweep]
        b.errorbar(g["_x"][~sweep], g[col][~sweep], yerr=err, fmt=mk, ms=6, mfc="none", color=colour, capsize=2,
                   label=f"{lab} (model, ± its bound)")
    if spans(list(g["alpha"]) + list(g["rop"])):
        b.set_yscale("log")
    b.set_xlabel(param)
    b.set_ylabel("NAND2 equivalents")
    b.set_title(f"gates against {param}")
    b.grid(alpha=.3, which="both")
    b.legend(**below)
    if spans(agg["rop"]):
        c.set_xscale("log")
    c.set_xlabel("NAND2 equivalents, LK units of one ROP")
    c.set_ylabel("RMSE (8-bit units)")
    c.set_title(f"quality against gates (numbers: {param})")
    c.grid(alpha=.3, which="both")
    c.legend(**below)
    for ax in (a, b, c):
        for axis in (ax.xaxis, ax.yaxis):
            if isinstance(axis.get_major_formatter(), matplotlib.ticker.ScalarFormatter):
                axis.get_major_formatter().set_useOffset(False)
                axis.get_major_formatter().set_scientific(False)
    fig.suptitle(title or f"quality against {param} against gates", x=0.01, ha="left")
    if out is None:
        return fig
    fig.savefig(out, dpi=96)
    plt.close(fig)
    return None


def main(argv):
    args = argv[1:]
    if not args or args[0] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 0 if args else 2
    for name in ("--param", "--spp", "--method", "--markdown", "--plot"):
        if name in args and args.index(name) + 1 >= len(args):
            print(f"study_cost: error: {name} needs a value", file=sys.stderr)
            return 1
    if "--param" not in args:
        print("study_cost: error: --param P is required (a swept numeric parameter, e.g. hash_bits)", file=sys.stderr)
        return 1

    def opt(name):
        return args[args.index(name) + 1] if name in args else None

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import study_report

    study_dir, param = args[0], opt("--param")
    try:
        spp = int(opt("--spp")) if opt("--spp") else None
    except ValueError:
        print(f"study_cost: error: --spp {opt('--spp')}: not an integer", file=sys.stderr)
        return 1
    try:
        name, _, df, _ = study_report.load(study_dir)
    except study_report.StudyError as e:
        print(f"study_cost: error: {study_dir}: {e}", file=sys.stderr)
        return 1
    if param not in df.columns:
        print(f"study_cost: error: {study_dir}: no parameter {param}", file=sys.stderr)
        return 1
    agg, reasons = cost_frame(df, param, spp, opt("--method"))
    if agg.empty or agg["rop"].isna().all():
        why = "; ".join(reasons) if reasons else "no point with an RMSE and a silicon cost"
        print(f"study_cost: error: {study_dir}: {why}", file=sys.stderr)
        return 1
    text = markdown(agg, param)
    if opt("--markdown"):
        with open(opt("--markdown"), "w") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    if opt("--plot"):
        plot(agg, param, opt("--plot"),
             f"study {name}: quality against {param} against gates" + (f" ({spp} spp)" if spp else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
