"""The study report's section "Fidelities" (analysis/study_report.py): in a
study of more than one fidelity, each point against the cycle model's
point of the same parameters (analysis/fidelity.py), as tables and a plot.
"""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import fidelity  # noqa: E402
from study_report_figures import panel_grid, put_legend  # noqa: E402
from study_report_load import fmt_value  # noqa: E402


def fidelity_keys(df, params):
    """The parameters that name a comparison of fidelities: the input and
    every other varying parameter but the fidelity and the seed."""
    return [p for p in params if p == "input" or (p not in fidelity.NOT_KEYS and df[p].nunique(dropna=True) > 1)]


def yes_no(v):
    return "" if v is None or (isinstance(v, float) and np.isnan(v)) else ("yes" if v else "no")


def pct_text(v):
    return "" if v is None or not np.isfinite(v) else f"{v:+.2f} %"


def interval_text(lo, hi):
    return "" if not (np.isfinite(lo) and np.isfinite(hi)) else f"[{fmt_value(round(lo))}, {fmt_value(round(hi))}]"


def section_fidelity(rep, df, params):
    """A study of more than one fidelity: each point's estimates (with the
    sampled 95 % intervals) against the cycle model's point of the same
    parameters, and its host time and speed-up (analysis/fidelity.py)."""
    ok = df[df["status"] == "ok"]
    if "fidelity" not in ok.columns or ok["fidelity"].nunique(dropna=True) < 2:
        return
    rep.heading(2, "Fidelities", "fidelities")
    shown = df.copy()
    if "design" in shown.columns:
        shown["design"] = [fidelity.design_name(v) if isinstance(v, str) else None for v in shown["design"]]
    keys = fidelity_keys(shown, params)
    pts = fidelity.points(shown)
    res = fidelity.compare(shown, keys)
    if not (pts["fidelity"] == "cycle").any():
        rep.para("No cycle point ran, so the other fidelities have nothing to be compared with; their host times: "
                 + ", ".join(f"{f} {pts[pts['fidelity'] == f]['wall_s'].mean():.3g} s per point"
                             for f in pd.unique(pts["fidelity"])) + ".")
        return
    if res.empty:
        rep.para("No point has a cycle point of the same parameters to be compared with.")
        return
    summ = fidelity.summary(pts, res)
    rep.para("Each point against the cycle model's point of the same " + ", ".join(keys) + " (a point without a "
             "parameter, as a functional point has no design, against the mean of the cycle points it matches). "
             "Errors are (estimate − cycle model) / cycle model; a sampled point's 95 % intervals should hold the "
             "cycle model's value. Host time: the point's host.wall_seconds; speed-up: the cycle points' host time "
             "over it.")
    rows = []
    for _, r in summ.iterrows():
        f = r["fidelity"]
        host = pts[pts["fidelity"] == f]["wall_s"]
        if r.get("reference") is True:
            rows.append([f, int(r["pairs"]), round(float(host.mean()), 3), "1 (the reference)", "the reference", "",
                         "", "the reference", "", ""])
            continue
        timed = not pd.isna(r.get("cycles_mae_pct", np.nan))
        cov = r.get("coverage_cycles", np.nan)
        rows.append([f, int(r["pairs"]), round(float(host.mean()), 3), f"{r['speedup_vs_cycle']:.2f}",
                     f"{r['cycles_mae_pct']:.2f} %" if timed else "no timing",
                     f"{r['cycles_max_pct']:.2f} %" if timed else "",
                     "" if pd.isna(cov) else f"{cov:.0%}",
                     f"{r['bytes_mae_pct']:.2f} %" if timed else "no timing",
                     f"{r['bytes_max_pct']:.2f} %" if timed else "",
                     f"{r['bottleneck_agreement']:.0%}" if timed else ""])
    rep.table(["fidelity", "points", "host s per point (mean)", "speed-up over cycle", "total cycles: mean |error|",
               "max |error|", "cycle value in the 95 % interval", "DRAM bytes: mean |error|", "max |error|",
               "bottleneck as the cycle model's"], rows,
              caption="Per fidelity: host time, speed-up over the cycle model (its points' host time over theirs, "
                      "each cycle point counted once per point compared with it) and the errors against it.")
    others = [k for k in keys if k != "input"]
    res = res.assign(_label=[", ".join([fmt_value(r["input"])] + [f"{k}={fmt_value(r[k])}" for k in others
                                                                  if not pd.isna(r[k])]) for _, r in res.iterrows()])
    rows = []
    for _, r in res.iterrows():
        rows.append([r["_label"], r["fidelity"], fmt_value(round(r["cycles"])) if np.isfinite(r["cycles"]) else "",
                     interval_text(r["cycles_lo"], r["cycles_hi"]),
                     fmt_value(round(r["cycle_cycles"])) if np.isfinite(r["cycles"]) else "",
                     pct_text(r["cycles_err_pct"]), yes_no(r["covers_cycles"]), pct_text(r["read_err_pct"]),
                     yes_no(r["covers_read"]), pct_text(r["written_err_pct"]), yes_no(r["covers_written"]),
                     r["bottleneck"] or "", yes_no(r["bottleneck_ok"]), round(float(r["host_s"]), 3),
                     round(float(r["speedup"]), 2)])
    rep.table(["point", "fidelity", "total cycles", "95 % interval", "cycle model", "cycles error",
               "cycle value in interval", "DRAM read error", "in interval", "DRAM written error", "in interval",
               "bottleneck", "as the cycle model's", "host s", "speed-up"], rows,
              caption="Each point against the cycle model: its estimate of total cycles with the 95 % interval "
                      "(sampled points), the relative errors of total cycles and of DRAM bytes read and written, "
                      "whether the cycle model's value lies in the interval, the bottleneck class, host time and "
                      "speed-up.")
    timed = res[res["cycles"].notna()]
    labels = list(pd.unique(res["_label"]))
    fids = list(pd.unique(res["fidelity"]))
    colours = {f: plt.get_cmap("tab10")(i) for i, f in enumerate(["functional", "approximate", "sampled", "cycle"] +
                                                                 [f for f in fids if f not in
                                                                  ("functional", "approximate", "sampled", "cycle")])}
    panels = [("cycles", "cycles_err_pct", "cycles_lo", "cycles_hi", "cycle_cycles", "total cycles"),
              ("read", "read_err_pct", "read_lo", "read_hi", "cycle_read", "DRAM bytes read"),
              ("written", "written_err_pct", "written_lo", "written_hi", "cycle_written", "DRAM bytes written")]
    if timed.empty:
        panels = []
    fig, axes, lax = panel_grid(len(panels) + 1, 4, panel_w=2.6 if panels else 5.0,
                                panel_h=0.3 * len(labels) + 1.6, sharey=True)
    y = {lab: i for i, lab in enumerate(labels)}
    nf = max(1, len(fids))
    for ax, (name, err, lo, hi, truth, title) in zip(axes, panels):
        for fi, f in enumerate(fids):
            g = timed[timed["fidelity"] == f]
            if g.empty:
                continue
            yy = np.array([y[lab] for lab in g["_label"]]) + (fi - (nf - 1) / 2) * 0.18
            xerr = None
            if lo and g[lo].notna().any():
                t = g[truth].to_numpy(float)
                rel = (lambda v: np.divide(100.0 * (v - t), t, out=np.full_like(t, np.nan), where=t != 0))
                lo_e, hi_e = rel(g[lo].to_numpy(float)), rel(g[hi].to_numpy(float))
                x = g[err].to_numpy(float)
                xerr = np.vstack([np.where(np.isfinite(lo_e), x - lo_e, 0), np.where(np.isfinite(hi_e), hi_e - x, 0)])
            ax.errorbar(g[err], yy, xerr=xerr, fmt="o", ms=5, capsize=3, color=colours[f], label=f)
        ax.axvline(0, color="k", lw=1, label="cycle model")
        ax.set_title(title)
        ax.set_xlabel("error (%)")
        ax.grid(alpha=.3)
    ax = axes[len(panels)]
    for fi, f in enumerate(fids + ["cycle"]):
        g = pts[pts["fidelity"] == f] if f == "cycle" else res[res["fidelity"] == f]
        if f == "cycle":
            g = res.drop_duplicates("_label")
            x = g["cycle_host_s"].to_numpy(float)
        else:
            x = g["host_s"].to_numpy(float)
        yy = np.array([y[lab] for lab in g["_label"]]) + (fi - nf / 2) * 0.18
        ax.plot(x, yy, "o" if f != "cycle" else "s", ms=5, color=colours[f], ls="none",
                label=f if f != "cycle" else "cycle (host time)")
    ax.set_xscale("log")
    ax.set_title("host time per point (s)")
    ax.set_xlabel("host.wall_seconds (s)")
    ax.grid(alpha=.3, which="both")
    axes[0].set_yticks(range(len(labels)), labels)
    axes[0].invert_yaxis()
    for a in axes[1:]:
        a.tick_params(labelleft=False)
    put_legend(lax, axes, title="fidelity")
    fig.suptitle("against the cycle model: " + ("error, 95 % interval (sampled), " if panels else "") + "host time",
                 x=0.01, ha="left")
    rep.figure(fig, "Each point's error in total cycles and DRAM bytes against the cycle model's point of the same "
                    "parameters (bars: the 95 % interval, sampled points), and each point's host time",
               "fidelity")

