"""The study report's sections on metrics (analysis/study_report.py):
quality against silicon (analysis/study_cost.py), every swept parameter
against the key metrics, and the bottlenecks with the cycles by activity.
"""
import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib import ticker  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import fidelity  # noqa: E402
from study_report_figures import DPI, panel_grid, put_legend, spans_decade  # noqa: E402
from study_report_load import (ACTIVITIES, BOTTLENECK, CYCLES, DRAM_R, DRAM_W, RMSE, SAMPLES, fmt_value,  # noqa: E402
                               is_cycle, num, sorted_values, varying)

SILICON_ROP = "silicon.per_rop.nand2_eq"
FRAME_US = "timing.frame_time_us"
KEY_METRICS = [(RMSE, "RMSE (8-bit units)"), ("vs_reference.bias_8bit", "bias (8-bit units, signed)"),
               (CYCLES, "total cycles"), (FRAME_US, "frame time (µs)"), ("_dram", "DRAM bytes (read + written)"),
               (SAMPLES, "samples written"), (SILICON_ROP, "NAND2 eq., LK units of a ROP")]


def section_silicon(rep, df, params):
    """RMSE beside the silicon cost (silicon.*, docs/rtl.md): for each swept
    numeric parameter the cost changes with, a table and three panels
    (analysis/study_cost.py)."""
    rep.heading(2, "Quality against silicon", "silicon")
    ok = df[df["status"] == "ok"]
    cost = num(ok, SILICON_ROP)
    if not ok.empty and cost.notna().any() and cost.isna().any():
        rep.para(f"{int(cost.isna().sum())} of {len(ok)} points have no silicon cost (their methods' units have no "
                 "reference RTL, or a unit lies outside the models: silicon.reason); the tables hold the others.")
    if ok.empty or cost.notna().sum() == 0:
        reasons = sorted({str(r) for r in ok.get("silicon.reason", pd.Series(dtype=str)).dropna() if str(r)})
        rep.para("No point has a silicon cost" + (": " + "; ".join(reasons[:3]) if reasons else "") + ".")
        return
    if num(ok, RMSE).notna().sum() == 0:
        rep.para("No point has an RMSE against a reference (reference = false), so the cost has nothing to stand "
                 "beside; the parameters-against-metrics plots show it.")
        return
    import study_cost

    ok, cost = ok[cost.notna()], cost[cost.notna()]
    shown = 0
    for p in params:
        if p == "input" or pd.to_numeric(ok[p], errors="coerce").isna().any() or ok[p].nunique() < 2:
            continue
        # a parameter the cost changes with: more than one cost among points that differ only in it
        if ok.assign(_c=cost).groupby(p)["_c"].mean().nunique() < 2:
            continue
        spps = sorted(pd.unique(num(ok, "spp").dropna())) if "spp" in ok.columns and p != "spp" else [None]
        for spp in spps:
            agg, _ = study_cost.cost_frame(ok, p, spp)
            if agg.empty or agg["rop"].isna().all():
                continue
            head, rows = study_cost.table(agg, p)
            tag = f" at {int(spp)} spp" if spp is not None else ""
            rep.table(head, rows, caption=f"RMSE (mean ± sd over the other parameters) and bias against {p}{tag}, "
                                          "beside the silicon cost of each value: NAND2 equivalents of the "
                                          "alpha-reference generator, of the LK units of one ROP and of the "
                                          "design, a sweep row or a model estimate within its bound")
            rep.figure(study_cost.plot(agg, p, None, f"quality against {p} against gates{tag}"),
                       f"RMSE against {p}, gates against {p}, RMSE against gates{tag}", f"silicon:{p}{tag}")
            shown += 1
    if not shown:
        rep.para("The silicon cost is the same at every point: no swept parameter changes it.")


def swept(ok, params):
    """The swept parameters with more than one value among the points that
    set them (a hardware key only on the cycle points, say), but the method,
    which tells the lines apart: (name, numeric)."""
    out = []
    for p in params:
        if p in ("input", "method", "seed"):
            continue
        vals = ok[p].dropna()
        if vals.nunique() < 2:
            continue
        out.append((p, bool(pd.to_numeric(vals, errors="coerce").notna().all())))
    return out


def value_name(v):
    """A parameter value as a tick label: a file (a design) by its stem."""
    if isinstance(v, str) and ("/" in v or v.endswith(".toml")):
        return fidelity.design_name(v)
    return fmt_value(v)


def section_axes(rep, df, params):
    rep.heading(2, "Parameters against metrics", "axes")
    ok = df[df["status"] == "ok"].copy()
    ok["_dram"] = num(ok, DRAM_R) + num(ok, DRAM_W)
    axes_ = swept(ok, params) if not ok.empty else []
    if not axes_:
        rep.para("No swept parameter has more than one value among the points that ran, so there is no "
                 "parameter-against-metric plot.")
        return
    has_method = "method" in ok.columns
    inputs = list(pd.unique(ok["input"])) if "input" in ok.columns else [None]
    methods = list(pd.unique(ok["method"])) if has_method else ["points"]
    colours = plt.get_cmap("tab10")
    for p, numeric in axes_:
        for inp in inputs:
            s = ok if inp is None else ok[ok["input"] == inp]
            s = s[s[p].notna()]
            metrics = [(c, t) for c, t in KEY_METRICS if num(s, c).notna().any()]
            if s.empty or not metrics:
                continue
            values = sorted_values(s[p])
            pos = {v: i for i, v in enumerate(values)}
            s = s.assign(_x=pd.to_numeric(s[p]) if numeric else s[p].map(pos))
            fig, axs, lax = panel_grid(len(metrics), 4, panel_w=2.75, panel_h=2.6)
            for ax, (col, title) in zip(axs, metrics):
                t = s.assign(_y=num(s, col))
                t = t[t["_y"].notna()]
                for m, g in (t.groupby("method", sort=False) if has_method else [("points", t)]):
                    g = g.groupby("_x")["_y"].mean().sort_index()
                    ax.plot(g.index, g.values, "o-", label=f"{m}", ms=4, color=colours(methods.index(m) % 10))
                ax.set_title(title)
                ax.set_xlabel(p)
                ax.grid(alpha=.3, which="both")
                ys = t["_y"].to_numpy(float)
                if spans_decade(ys):
                    ax.set_yscale("log")
                if numeric:
                    xs = sorted(float(v) for v in pd.to_numeric(pd.Series(values)))
                    if spans_decade(xs) or (xs[0] > 0 and xs[-1] / xs[0] >= 8):
                        ax.set_xscale("log", base=2)
                    ax.set_xticks(xs, [fmt_value(v) for v in values])
                    ax.xaxis.set_minor_locator(ticker.NullLocator())
                else:
                    names = [value_name(v) for v in values]
                    long = sum(len(n) for n in names) * 7 > 2.75 * DPI * 0.8
                    ax.set_xticks(range(len(values)), names, rotation=90 if long else 0)
                    ax.set_xlim(-0.5, len(values) - 0.5)
            put_legend(lax, axs, title="method")
            where = f"{inp}: " if inp is not None else ""
            fig.suptitle(f"{where}key metrics against {p} (mean over the other parameters)", x=0.01, ha="left")
            rep.figure(fig, f"{where}key metrics against {p}, one line per method, each point the mean over the "
                            "points of that value", f"axes:{p}:{inp}")


def unit_activity(df):
    """Cycles by activity summed per (method, unit kind) from the reports."""
    rows = []
    for _, r in df.iterrows():
        try:
            rep = json.loads(r["report"]) if isinstance(r.get("report"), str) else None
        except ValueError:
            rep = None
        units = ((rep or {}).get("timing") or {}).get("units") or []
        for u in units:
            cyc = u.get("cycles") or {}
            row = {"method": r.get("method", "all"), "kind": u.get("kind", "?")}
            for a in ACTIVITIES:
                row[a] = float(cyc.get(a, 0) or 0)
            rows.append(row)
    return pd.DataFrame(rows)


def section_bottlenecks(rep, df, params):
    rep.heading(2, "Bottlenecks and stall reasons", "bottlenecks")
    cyc = df[(df["status"] == "ok") & is_cycle(df)].copy()
    if cyc.empty or BOTTLENECK not in cyc.columns:
        rep.para("No cycle-fidelity point ran, so there are no bottlenecks or stall reasons "
                 "(set fidelity = \"cycle\" on an axis).")
        return
    cyc["_class"] = cyc[BOTTLENECK].fillna("").astype(str).str.split(":", n=1).str[0].str.strip()
    cyc.loc[cyc["_class"] == "", "_class"] = "(none)"
    by = ["method"] if "method" in cyc.columns else []
    by += varying(cyc, params, exclude=("method", "fidelity"))
    for b in by:
        ct = pd.crosstab(cyc[b], cyc["_class"])
        ct = ct.loc[[v for v in sorted_values(cyc[b]) if v in ct.index]]
        rep.table([b] + list(ct.columns), [[i] + [int(v) for v in ct.loc[i]] for i in ct.index],
                  caption=f"Bottleneck class (timing.bottleneck before the ':') of the cycle points, counted per {b}.")
    key = by[0] if by else None
    colours = plt.get_cmap("tab10")
    if key:
        ct = pd.crosstab(cyc[key], cyc["_class"])
        ct = ct.loc[[v for v in sorted_values(cyc[key]) if v in ct.index]]
        fig, (ax,), lax = panel_grid(1, 1, panel_w=min(8.0, max(4.0, 0.9 * len(ct) + 2)), panel_h=3.4)
        bottom = np.zeros(len(ct))
        x = np.arange(len(ct))
        for ci, c in enumerate(ct.columns):
            ax.bar(x, ct[c].to_numpy(), bottom=bottom, label=c, color=colours(ci % 10))
            bottom += ct[c].to_numpy()
        ax.set_xticks(x, [fmt_value(i) for i in ct.index])
        ax.set_xlabel(key)
        ax.set_ylabel("cycle points")
        ax.yaxis.set_major_locator(ticker.MaxNLocator(integer=True))
        ax.set_title(f"bottleneck class per {key}")
        put_legend(lax, [ax], title="bottleneck class")
        rep.figure(fig, f"Bottleneck class of the cycle points per {key}", f"bottlenecks:{key}")
    act = unit_activity(cyc)
    if act.empty:
        rep.para("The cycle points' reports hold no timing.units, so there is no breakdown by activity.")
        return
    totals = act.groupby("kind", sort=False)[ACTIVITIES].sum()
    rep.table(["unit kind"] + ACTIVITIES, [[k] + [int(v) for v in totals.loc[k]] for k in totals.index],
              caption="Cycles by activity summed per unit kind over every cycle point.")
    methods = list(pd.unique(act["method"]))
    kinds = list(pd.unique(act["kind"]))
    fig, axes, lax = panel_grid(len(methods), 3, panel_w=3.5, panel_h=0.32 * len(kinds) + 1.4, sharey=True)
    for ax, m in zip(axes, methods):
        t = act[act["method"] == m].groupby("kind", sort=False)[ACTIVITIES].sum().reindex(kinds).fillna(0)
        total = t.sum(axis=1).replace(0, np.nan)
        share = t.div(total, axis=0).fillna(0) * 100.0
        y = np.arange(len(kinds))
        left = np.zeros(len(kinds))
        for ai, a in enumerate(ACTIVITIES):
            ax.barh(y, share[a].to_numpy(), left=left, label=a, color=colours(ai), height=0.75)
            left += share[a].to_numpy()
        ax.set_yticks(y, kinds)
        ax.set_xlim(0, 100)
        ax.set_xlabel("share of the unit's cycles (%)")
        ax.set_title(f"{m}")
        ax.grid(alpha=.3, axis="x")
    axes[0].invert_yaxis()
    for i, ax in enumerate(axes):
        if i % 3:
            ax.tick_params(labelleft=False)
    put_legend(lax, axes, title="activity")
    fig.suptitle("share of cycles by activity per unit kind", x=0.01, ha="left")
    rep.figure(fig, "Share of each unit kind's cycles by activity, one panel per method", "activity")

