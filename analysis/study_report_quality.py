"""The study report's first sections (analysis/study_report.py): the points
and failures, quality against cost with the Pareto front, and equal
quality (spp_at_rmse: where a curve reaches a target RMSE).
"""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from study_report_figures import MIN_TEXT_PT, panel_grid, put_legend, spans_decade  # noqa: E402
from study_report_load import (CYCLES, DRAM_R, DRAM_W, RMSE, STATE_R, STATE_W, fmt_value, is_cycle,  # noqa: E402
                               num, params_text, sorted_values, varying)


def section_points(rep, name, declared, df, params):
    ok = int((df["status"] == "ok").sum())
    failed = int((df["status"] != "ok").sum())
    rep.heading(2, "Points", "points")
    missing = max(0, declared - len(df))
    text = f"{declared} points: {ok} ok, {failed} failed"
    if missing:
        text += f", {missing} not run yet"
    rep.para(text + ".")
    rep.table(["parameter", "values"], [[p, ", ".join(fmt_value(v) for v in sorted_values(df[p]))] for p in params],
              caption="Parameters of the points.")
    rep.heading(3, "Failures", "failures")
    bad = df[df["status"] != "ok"]
    if bad.empty:
        rep.para("No point failed.")
    else:
        rep.table(["point", "parameters", "error"],
                  [[r["point"], params_text(r, params), r.get("error", "")] for _, r in bad.iterrows()])


def curve_key(params, df, extra_exclude=()):
    """The parameters that tell the curves apart: method and whatever else varies."""
    others = varying(df, params, exclude=("input", "method", "spp", "fidelity", "seed") + tuple(extra_exclude))
    return (["method"] if "method" in df.columns else []) + others


def label_of(keys, vals):
    if not keys:
        return "points"
    vals = vals if isinstance(vals, tuple) else (vals,)
    parts = [fmt_value(v) if k == "method" else f"{k}={fmt_value(v)}" for k, v in zip(keys, vals)]
    return ", ".join(parts)


def pareto(cost, err):
    """Indices (into the arrays) of the points no other point beats in both."""
    order = np.lexsort((err, cost))
    front, best = [], np.inf
    for i in order:
        if err[i] < best:
            front.append(i)
            best = err[i]
    return front


def one_clock(df):
    """The ROP clock in GHz when every point of df has the same one, else None."""
    ghz = num(df, "timing.clock_ghz").dropna().unique()
    return float(ghz[0]) if len(ghz) == 1 and ghz[0] > 0 else None


def frame_time_axis(ax, ghz):
    """A top axis of frame time (µs) over an axis of cycles at ghz GHz."""
    sec = ax.secondary_xaxis("top", functions=(lambda c: c / (ghz * 1e3), lambda us: us * ghz * 1e3))
    sec.set_xlabel(f"frame time (µs) at {ghz:g} GHz")
    return sec


def section_quality(rep, df, params):
    rep.heading(2, "Quality against cost", "quality")
    ok = df[(df["status"] == "ok")].copy()
    ok["_rmse"] = num(ok, RMSE)
    ok = ok[ok["_rmse"].notna()]
    if ok.empty:
        rep.para("No point has an RMSE against a reference (the study sets reference = false, or every point "
                 "failed), so there is no quality-against-cost plot.")
        return
    cyc = is_cycle(ok)
    ok["_dram"] = num(ok, DRAM_R) + num(ok, DRAM_W)
    ok["_state"] = num(ok, STATE_R) + num(ok, STATE_W)
    ok["_cycles"] = num(ok, CYCLES)
    plots = [
        ("cycle", "_dram", "DRAM bytes (read + written)", ok[cyc]),
        ("cycle", "_cycles", "total cycles", ok[cyc]),
        ("functional", "_state", "state bytes (read + written)", ok[~cyc]),
    ]
    if not cyc.any():
        rep.para("No cycle-fidelity point: RMSE against DRAM bytes and against cycles needs fidelity = \"cycle\"; "
                 "the functional points' state bytes stand for the memory traffic below.")
    pareto_rows = []
    for fid, col, what, sub in plots:
        sub = sub[sub[col].notna()]
        if sub.empty:
            continue
        inputs = list(pd.unique(sub["input"])) if "input" in sub.columns else [None]
        keys = curve_key(params, sub)
        curves = [label_of(keys, tuple(r)) for r in sub[keys].drop_duplicates().itertuples(index=False)] if keys \
            else ["points"]
        colours = plt.get_cmap("tab10" if len(curves) <= 10 else "tab20")
        fig, axes, lax = panel_grid(len(inputs), 3, panel_w=3.9, panel_h=3.4)
        ghz = one_clock(sub) if col == "_cycles" else None
        for ax, inp in zip(axes, inputs):
            s = sub if inp is None else sub[sub["input"] == inp]
            group_cols = keys + (["spp"] if "spp" in s.columns else [])
            # Several points per curve and spp (seeds, fidelities): their mean.
            agg = s.groupby(group_cols, dropna=False)[[col, "_rmse"]].mean().reset_index() if group_cols else s
            groups = agg.groupby(keys if len(keys) > 1 else keys[0], sort=False) if keys else [((), agg)]
            for gk, g in groups:
                g = g.assign(_spp=num(g, "spp")).sort_values("_spp") if "spp" in g.columns else g
                lab = label_of(keys, gk)
                if lab not in curves:
                    curves.append(lab)
                ax.plot(g[col], g["_rmse"], "o-", label=lab, ms=5, color=colours(curves.index(lab) % colours.N))
                if "spp" in g.columns:
                    for _, r in g.iterrows():
                        ax.annotate(fmt_value(r["spp"]), (r[col], r["_rmse"]), textcoords="offset points",
                                    xytext=(4, 3), fontsize=MIN_TEXT_PT, color="#333")
            c, e = agg[col].to_numpy(float), agg["_rmse"].to_numpy(float)
            front = pareto(c, e)
            ax.step(c[front], e[front], where="post", color="k", lw=1, ls="--", alpha=.6)
            ax.plot(c[front], e[front], "o", ms=11, mfc="none", mec="k", label="Pareto front")
            for i in front:
                r = agg.iloc[i]
                pareto_rows.append([fid, fmt_value(inp), label_of(keys, tuple(r[k] for k in keys)),
                                    fmt_value(r["spp"]) if "spp" in agg.columns else "", what, c[i], e[i]])
            ax.set_xscale("log" if spans_decade(c) else "linear")
            ax.set_yscale("log" if spans_decade(e) else "linear")
            ax.margins(x=0.12, y=0.12)
            ax.set_xlabel(what)
            ax.set_ylabel("RMSE (8-bit units)")
            ax.set_title(f"{inp}" if inp is not None else "all inputs")
            ax.grid(alpha=.3, which="both")
            if ghz:
                frame_time_axis(ax, ghz)
        put_legend(lax, axes, title="curve (numbers: spp)")
        fig.suptitle(f"RMSE against {what}, {fid} points", x=0.01, ha="left")
        rep.figure(fig, f"RMSE against {what}, {fid} points: one panel per input, one curve per "
                        "method, spp beside each point, the Pareto front circled"
                   + (f"; top axis: the frame time at {ghz:g} GHz" if ghz else ""), f"quality:{col[1:]}")
    if pareto_rows:
        rep.table(["fidelity", "input", "curve", "spp", "cost", "cost value", "RMSE"], pareto_rows,
                  caption="The Pareto front: points no other point of the same input beats in both cost and RMSE.")


def spp_at_rmse(spp, rmse, target):
    """Where a curve reaches a target RMSE, between its swept spp (docs/studies.md "Equal quality").

    The curve is made monotone first: at each swept spp, the least RMSE at that spp or below
    (r_k = min over j <= k). Between the adjacent swept s_a < s_b with r_a > t >= r_b,
    log(RMSE) is linear in log2(spp):
        log2 s = log2 s_a + f * (log2 s_b - log2 s_a),   f = (ln r_a - ln t) / (ln r_a - ln r_b)
    (linear in RMSE when r_b = 0). Returns ("in", s, a, b, f) with a, b indices into the points
    sorted by spp; ("below", s_0, r_0) when the smallest swept spp already reaches t (the spp that
    just reaches it is at or below s_0: outside the swept range); ("above", s_n, r_n) when no swept
    spp reaches it. Nothing is extrapolated.
    """
    order = np.argsort(spp, kind="stable")
    s = np.asarray(spp, float)[order]
    r = np.minimum.accumulate(np.asarray(rmse, float)[order])
    if r[0] <= target:
        return ("below", s[0], r[0])
    if r[-1] > target:
        return ("above", s[-1], r[-1])
    b = int(np.argmax(r <= target))
    a = b - 1
    if r[b] > 0:
        f = (np.log(r[a]) - np.log(target)) / (np.log(r[a]) - np.log(r[b]))
    else:
        f = (r[a] - target) / (r[a] - r[b])
    return ("in", float(2 ** (np.log2(s[a]) + f * (np.log2(s[b]) - np.log2(s[a])))), order[a], order[b], f)


def section_equal_quality(rep, df, params):
    """For target RMSEs, the spp at which each curve reaches them (interpolated) and its cost there."""
    rep.heading(2, "Equal quality", "equal-quality")
    ok = df[(df["status"] == "ok")].copy()
    ok["_rmse"] = num(ok, RMSE)
    ok = ok[ok["_rmse"].notna()]
    if ok.empty or "spp" not in ok.columns or ok["spp"].nunique() < 2:
        rep.para("The equal-quality table needs an RMSE against a reference and at least two spp values.")
        return
    ok["_spp"] = num(ok, "spp")
    ok = ok[ok["_spp"] > 0]
    cyc = is_cycle(ok)
    ok["_dram"] = num(ok, DRAM_R) + num(ok, DRAM_W)
    ok["_state"] = num(ok, STATE_R) + num(ok, STATE_W)
    ok["_cycles"] = num(ok, CYCLES)
    sub, costs = (ok[cyc], [("_cycles", "cycles"), ("_dram", "DRAM bytes")]) if cyc.any() else \
        (ok[~cyc], [("_state", "state bytes")])
    # A named case (the column "case", docs/studies.md "Named cases") is a curve of its own.
    keys = curve_key(params + [c for c in ("case",) if c in sub.columns and c not in params], sub)
    rows = []
    inputs = list(pd.unique(sub["input"])) if "input" in sub.columns else [None]
    for inp in inputs:
        s = sub if inp is None else sub[sub["input"] == inp]
        agg = s.groupby(keys + ["_spp"], dropna=False)[["_rmse"] + [c for c, _ in costs]].mean().reset_index()
        best = agg.groupby("_spp")["_rmse"].min().sort_index()
        # The targets: what the best curve reaches at each spp (rounded up a little).
        targets = sorted({float(f"{v * 1.02:.3g}") for v in best.to_numpy(float)}, reverse=True)[:6]
        groups = agg.groupby(keys if len(keys) > 1 else keys[0], sort=False) if keys else [((), agg)]
        for t in targets:
            for gk, g in groups:
                g = g.reset_index(drop=True)
                label = label_of(keys, gk)
                at = spp_at_rmse(g["_spp"].to_numpy(float), g["_rmse"].to_numpy(float), t)
                if at[0] == "below":
                    rows.append([fmt_value(inp), t, label,
                                 f"at or below {fmt_value(at[1])}: outside the swept range", "",
                                 f"{at[2]:.3g} at {fmt_value(at[1])} spp"] + ["" for _ in costs])
                elif at[0] == "above":
                    rows.append([fmt_value(inp), t, label,
                                 f"above {fmt_value(at[1])}: outside the swept range", "",
                                 f"best {at[2]:.3g} at {fmt_value(at[1])} spp"] + ["" for _ in costs])
                else:
                    _, spp, a, b, f = at
                    ra, rb = g.loc[a], g.loc[b]
                    cost = []
                    for c, _ in costs:
                        ca, cb = float(ra[c]), float(rb[c])
                        v = ca ** (1 - f) * cb ** f if ca > 0 and cb > 0 else ca + f * (cb - ca)
                        cost.append("" if np.isnan(v) else int(round(v)))
                    rows.append([fmt_value(inp), t, label, f"{spp:.3g}",
                                 f"{fmt_value(ra['_spp'])}-{fmt_value(rb['_spp'])}",
                                 f"{ra['_rmse']:.3g} / {rb['_rmse']:.3g}"] + cost)
    fidelity = "cycle" if cyc.any() else "functional"
    rep.table(["input", "target RMSE", "curve", "spp", "between swept spp", "RMSE at them"] + [w for _, w in costs],
              rows,
              caption=f"For each target RMSE t (8-bit units; what the best curve reaches at each swept spp, "
                      f"x 1.02), the spp at which each curve reaches it, interpolated between the two swept spp "
                      f"s_a < s_b around it with log(RMSE) linear in log2(spp): log2 s = log2 s_a + f (log2 s_b - "
                      f"log2 s_a), f = (ln r_a - ln t) / (ln r_a - ln r_b), r the curve's RMSE made monotone "
                      f"(the least at that spp or below); its cost there interpolated with the same f, "
                      f"log(cost) linear in log2(spp). A target the smallest swept spp already reaches, or that "
                      f"no swept spp reaches, is outside the swept range and is not extrapolated "
                      f"({fidelity} points, means over the other parameters).")

