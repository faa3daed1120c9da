"""The study report's section "Against blend" (analysis/study_report.py):
each method against blend at the same condition, the marginal cost over
blend, the spp at which a method reaches blend's quality, and the frames
whose draws are all opaque.
"""
import numpy as np

from study_report_load import CYCLES, DRAM_R, DRAM_W, RMSE, fmt_value, num, params_text
from study_report_quality import spp_at_rmse

TRANSPARENT_SHARE = "frame.transparent_share"
# The methods whose marginal cost over blend the answer table gives first
# (docs/results.md "Real application frames"); any other method of the study follows.
HEADLINE = ("lk", "enderton", "hashed-a2c")


def condition_keys(df, params):
    """What a blend point is matched on: every swept parameter but the method."""
    return [p for p in params if p != "method" and p in df.columns and df[p].nunique(dropna=False) > 1] \
        or (["input"] if "input" in df.columns else [])


def against_blend_frame(df, params):
    """The ok points with blend's RMSE, cycles and DRAM bytes at the same
    condition (every other swept parameter equal; means over repeats), or
    None when the study has no blend point."""
    if "method" not in df.columns or not (df["method"].astype(str) == "blend").any():
        return None, []
    ok = df[df["status"] == "ok"].copy()
    ok["_rmse"] = num(ok, RMSE)
    ok["_cycles"] = num(ok, CYCLES)
    ok["_dram"] = num(ok, DRAM_R) + num(ok, DRAM_W)
    ok["_tshare"] = num(ok, TRANSPARENT_SHARE)
    keys = condition_keys(ok, params)
    agg = ok.groupby(keys + ["method"], dropna=False)[["_rmse", "_cycles", "_dram", "_tshare"]].mean().reset_index()
    base = agg[agg["method"].astype(str) == "blend"].drop(columns=["method", "_tshare"])
    base = base.rename(columns={"_rmse": "_b_rmse", "_cycles": "_b_cycles", "_dram": "_b_dram"})
    return agg.merge(base, on=keys, how="inner"), keys


def ratio(a, b):
    return a / b if b and np.isfinite(a) and np.isfinite(b) and b > 0 else np.nan


def section_against_blend(rep, df, params):
    """Each method against blend, today's ordered blending, at the same input,
    spp and design: RMSE, cycles and DRAM bytes with their ratios to blend,
    whether blend's order error is larger than the method's noise, the
    marginal cost over blend, and the spp at which a method reaches blend's
    quality (docs/studies.md "Against blend")."""
    m, keys = against_blend_frame(df, params)
    if m is None:
        return
    rep.heading(2, "Against blend", "against-blend")
    if m.empty:
        rep.para("No method has a blend point of the same input, spp and design to compare with.")
        return
    cond = [k for k in keys if k != "input"]
    others = m[m["method"].astype(str) != "blend"].copy()
    rows = []
    for _, r in others.sort_values(keys + ["method"], kind="stable").iterrows():
        worse = "" if not (np.isfinite(r["_rmse"]) and np.isfinite(r["_b_rmse"])) else \
            ("yes" if r["_b_rmse"] > r["_rmse"] else "no")
        rows.append([fmt_value(r["input"]) if "input" in r.index else "", params_text(r, cond), r["method"],
                     r["_rmse"], r["_b_rmse"], worse,
                     "" if np.isnan(r["_cycles"]) else int(round(r["_cycles"])), ratio(r["_cycles"], r["_b_cycles"]),
                     "" if np.isnan(r["_dram"]) else int(round(r["_dram"])), ratio(r["_dram"], r["_b_dram"])])
    rep.table(["input", "other parameters", "method", "RMSE", "blend's RMSE", "blend's error larger", "cycles", "x blend",
               "DRAM bytes", "x blend"],
              [[v if not isinstance(v, float) or not np.isfinite(v) or v == int(v) else float(f"{v:.4g}")
                for v in row] for row in rows],
              caption="Every method against blend (ordered blending in submission order with each draw's own "
                      "state) at the same input and the same other parameters (means over repeats). RMSE is "
                      "against the A-buffer reference of the same capture, in 8-bit units. blend's error is the "
                      "application's order error (it did not sort); 'blend's error larger' says whether that error "
                      "is above the method's own (its noise and its approximations). x blend: the method's cycles "
                      "and DRAM bytes (read + written) divided by blend's.")

    # The answer: the marginal cost over blend, and where the method reaches blend's quality.
    methods = [x for x in HEADLINE if x in set(others["method"].astype(str))] + \
        sorted(set(others["method"].astype(str)) - set(HEADLINE))
    group = [k for k in keys if k != "spp"]
    answer = []
    for gk, g in others.groupby(group if len(group) > 1 else group[0], dropna=False, sort=False) if group \
            else [((), others)]:
        gk = gk if isinstance(gk, tuple) else (gk,)
        where = dict(zip(group, gk))
        for meth in methods:
            s = g[g["method"].astype(str) == meth]
            if s.empty:
                continue
            s = s.assign(_spp=num(s, "spp")).sort_values("_spp") if "spp" in s.columns else s
            dc = ", ".join(f"{fmt_value(r['spp'])}: {r['_cycles'] - r['_b_cycles']:+,.0f}" if "spp" in s.columns
                           else f"{r['_cycles'] - r['_b_cycles']:+,.0f}" for _, r in s.iterrows())
            dd = ", ".join(f"{fmt_value(r['spp'])}: {r['_dram'] - r['_b_dram']:+,.0f} "
                           f"({ratio(r['_dram'], r['_b_dram']) - 1:+.0%})" if "spp" in s.columns
                           else f"{r['_dram'] - r['_b_dram']:+,.0f}" for _, r in s.iterrows())
            reach = ""
            if "spp" in s.columns and s["_spp"].nunique() >= 2 and s["_rmse"].notna().all():
                target = float(s["_b_rmse"].mean())
                at = spp_at_rmse(s["_spp"].to_numpy(float), s["_rmse"].to_numpy(float), target)
                reach = (f"at or below {fmt_value(at[1])} spp" if at[0] == "below" else
                         f"not by {fmt_value(at[1])} spp (RMSE {at[2]:.3g})" if at[0] == "above" else
                         f"{at[1]:.3g} spp")
                reach = f"{reach}; blend {target:.3g}"
            answer.append([fmt_value(where.get("input", "")),
                           ", ".join(f"{k}={fmt_value(v)}" for k, v in where.items() if k != "input"), meth,
                           dc, dd, reach])
    if answer:
        rep.table(["input", "other parameters", "method", "cycles over blend, by spp", "DRAM bytes over blend, by spp",
                   "reaches blend's RMSE"], answer,
                  caption="The marginal cost of each method over blend on the same frame: its cycles and DRAM bytes "
                          "less blend's at each swept spp (the share of blend's bytes in brackets), and the spp at "
                          "which its RMSE reaches blend's (the mean of blend's RMSE over the swept spp), "
                          "interpolated as in \"Equal quality\"; a frame on which blend is wrong because the "
                          "application did not sort is one where a method can beat it.")

    # Frames without a transparent sample: what each method pays for opaque draws.
    if m["_tshare"].notna().any():
        opaque = others[(others["_tshare"] == 0)]
        if not opaque.empty:
            rows = [[fmt_value(r["input"]), params_text(r, cond), r["method"], r["_rmse"] - r["_b_rmse"],
                     f"{r['_cycles'] - r['_b_cycles']:+,.0f}", f"{r['_dram'] - r['_b_dram']:+,.0f}"]
                    for _, r in opaque.sort_values(keys + ["method"], kind="stable").iterrows()]
            rep.table(["input", "other parameters", "method", "RMSE less blend's", "cycles over blend", "DRAM bytes over blend"],
                      rows,
                      caption="Frames whose draws are all opaque (frame.transparent_share = 0): blend is what a "
                              "z-buffer ROP pays for them, so these columns are what each method's treatment of "
                              "opaque draws costs beyond it (its image is blend's: RMSE less blend's is 0).")

