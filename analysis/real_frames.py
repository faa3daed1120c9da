#!/usr/bin/python3
"""The real-application-frames tables and figure of docs/results.md, from a study folder.

usage: real_frames.py DIR [DIR...] [--spp S] [--design NAME] [--methods M,M,...]
                      [--markdown OUT] [--plot PNG]

DIR is the folder of `ropsim study run studies/real-frames.toml` (any study
whose methods include blend and whose inputs are frames of draw states);
several folders are read as one (a study run in parts: the same axes, other
inputs). It writes, in Markdown (to OUT, else standard output):
  1. the frames: draws by kind, covered samples, the transparent share of the
     covered samples and of the screen, the transparent depth complexity;
  2. per frame and design at spp S (default 16): each method's RMSE against
     the A-buffer reference, its cycles and DRAM bytes and their ratios to
     blend's, and whether blend's (order) error is the larger;
  3. the answer: per frame and design, the marginal cost of lk, enderton and
     hashed-a2c over blend (cycles and DRAM bytes less blend's, at each spp)
     and the spp at which each reaches blend's RMSE;
--design keeps the points of one design (its file's stem, e.g. default)
in the tables, --methods the methods listed (blend is always kept); the
plot shows every design and method. With --plot, one panel per frame: RMSE against DRAM bytes (read +
written) of every method and spp, one marker per design, with the Pareto
front of each design.

Runs on /usr/bin/python3 with Debian's pandas, numpy and matplotlib.
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import study_report as sr  # noqa: E402

HEADLINE = sr.HEADLINE
FRAME_COLS = [("frame.covered_samples", "covered samples"),
              ("frame.transparent_share", "transparent: share of covered samples"),
              ("frame.transparent_screen_share", "transparent: share of the screen"),
              ("frame.translucent_share", "translucent (alpha < 1): share of covered samples"),
              ("frame.transparent_depth_complexity", "transparent depth complexity")]
KINDS = ["opaque", "src_over", "premultiplied_over", "additive", "other"]


def design_name(v):
    return os.path.splitext(os.path.basename(str(v)))[0] if isinstance(v, str) and v else sr.fmt_value(v)


def md_table(header, rows, text_cols=3):
    out = ["| " + " | ".join(header) + " |",
           "|" + "|".join("---" if i < text_cols else "---:" for i in range(len(header))) + "|"]
    out += ["| " + " | ".join(sr.fmt_value(v) for v in r) + " |" for r in rows]
    return "\n".join(out) + "\n"


def pct(v):
    return "" if v is None or not np.isfinite(v) else f"{100 * v:.1f} %"


def frames_table(df):
    ok = df[df["status"] == "ok"]
    rows = []
    for (inp, spp), g in ok.groupby(["input", "spp"], sort=True):
        r = g.iloc[0]
        kinds = ", ".join(f"{int(sr.num(g, 'draw_kinds.' + k).iloc[0]):,} {k.replace('_', '-')}"
                          for k in KINDS if sr.num(g, "draw_kinds." + k).fillna(0).iloc[0] > 0)
        vals = [sr.num(g, c).iloc[0] for c, _ in FRAME_COLS]
        rows.append([inp, sr.fmt_value(spp), kinds or "-", f"{int(vals[0]):,}" if np.isfinite(vals[0]) else "",
                     pct(vals[1]), pct(vals[2]), pct(vals[3]), f"{vals[4]:.2f}" if np.isfinite(vals[4]) else ""])
        del r
    return md_table(["frame", "spp", "fragments by draw kind", "covered samples"] + [w for _, w in FRAME_COLS[1:]],
                    rows)


def methods_table(m, spp):
    s = m[(sr.num(m, "spp") == spp)] if "spp" in m.columns else m
    rows = []
    keys = [k for k in ("input", "design") if k in s.columns]
    order = {x: i for i, x in enumerate(["blend"] + list(HEADLINE))}
    s = s.assign(_o=s["method"].map(lambda x: order.get(str(x), 99))).sort_values(keys + ["_o", "method"])
    for _, r in s.iterrows():
        blend = str(r["method"]) == "blend"
        rows.append([r["input"], design_name(r.get("design", "")), r["method"], f"{r['_rmse']:.3g}",
                     "" if blend else ("yes" if r["_b_rmse"] > r["_rmse"] else "no"),
                     f"{r['_cycles']:,.0f}", "1" if blend else f"{sr.ratio(r['_cycles'], r['_b_cycles']):.3f}",
                     f"{r['_dram']:,.0f}", "1" if blend else f"{sr.ratio(r['_dram'], r['_b_dram']):.3f}"])
    return md_table(["frame", "design", "method", "RMSE", "blend's error larger", "cycles", "x blend", "DRAM bytes",
                     "x blend"], rows)


def answer_table(m):
    rows = []
    keys = [k for k in ("input", "design") if k in m.columns]
    for gk, g in m.groupby(keys if len(keys) > 1 else keys[0], sort=True):
        gk = gk if isinstance(gk, tuple) else (gk,)
        where = dict(zip(keys, gk))
        for meth in HEADLINE:
            s = g[g["method"].astype(str) == meth].assign(_spp=lambda x: sr.num(x, "spp")).sort_values("_spp")
            if s.empty:
                continue
            dc = "; ".join(f"{int(r['_spp'])}: {r['_cycles'] - r['_b_cycles']:+,.0f} "
                           f"({sr.ratio(r['_cycles'], r['_b_cycles']) - 1:+.0%})" for _, r in s.iterrows())
            dd = "; ".join(f"{int(r['_spp'])}: {r['_dram'] - r['_b_dram']:+,.0f} "
                           f"({sr.ratio(r['_dram'], r['_b_dram']) - 1:+.0%})" for _, r in s.iterrows())
            target = float(s["_b_rmse"].mean())
            reach = ""
            if s["_spp"].nunique() >= 2:
                at = sr.spp_at_rmse(s["_spp"].to_numpy(float), s["_rmse"].to_numpy(float), target)
                reach = (f"at or below {int(at[1])}" if at[0] == "below" else
                         f"not by {int(at[1])} (RMSE {at[2]:.3g})" if at[0] == "above" else f"{at[1]:.3g}")
            rows.append([where.get("input", ""), design_name(where.get("design", "")), meth, dc, dd,
                         f"{target:.3g}", reach])
    return md_table(["frame", "design", "method", "cycles over blend, by spp", "DRAM bytes over blend, by spp",
                     "blend's RMSE", "spp reaching it"], rows)


def plot(m, path):
    inputs = sorted(pd.unique(m["input"]))
    designs = sorted(pd.unique(m["design"])) if "design" in m.columns else [None]
    methods = list(dict.fromkeys(["blend"] + list(HEADLINE) + sorted(pd.unique(m["method"].astype(str)))))
    colours = plt.get_cmap("tab10")
    markers = ["o", "s", "^", "D"]
    fig, axes, lax = sr.panel_grid(len(inputs), 2, panel_w=4.6, panel_h=3.8)
    for ax, inp in zip(axes, inputs):
        s = m[m["input"] == inp]
        for di, d in enumerate(designs):
            sd = s if d is None else s[s["design"] == d]
            for mi, meth in enumerate(methods):
                g = sd[sd["method"].astype(str) == meth].assign(_spp=lambda x: sr.num(x, "spp")).sort_values("_spp")
                if g.empty:
                    continue
                ax.plot(g["_dram"], g["_rmse"], marker=markers[di % len(markers)], ls="-" if di == 0 else ":",
                        color=colours(mi % 10), ms=5, label=f"{meth}, {design_name(d)}" if d is not None else meth)
            c, e = sd["_dram"].to_numpy(float), sd["_rmse"].to_numpy(float)
            ok = np.isfinite(c) & np.isfinite(e)
            c, e = c[ok], e[ok]
            if len(c):
                front = sr.pareto(c, e)
                ax.step(c[front], e[front], where="post", color="k", lw=1, ls="--" if di == 0 else ":", alpha=.7,
                        label=f"Pareto front, {design_name(d)}" if d is not None else "Pareto front")
        ax.set_xscale("log" if sr.spans_decade(s["_dram"]) else "linear")
        # A frame of opaque draws only has RMSE 0 for every method: a linear axis.
        ax.set_yscale("log" if (s["_rmse"] > 0).all() else "linear")
        ax.margins(x=0.08, y=0.1)
        if not (s["_rmse"] > 0).all():
            ax.set_ylim(0, max(1.0, 1.15 * float(s["_rmse"].max())))
        ax.set_xlabel("DRAM bytes (read + written)")
        ax.set_ylabel("RMSE (8-bit units)")
        ax.set_title(str(inp))
        ax.grid(alpha=.3, which="both")
    sr.put_legend(lax, axes, title="method, design")
    fig.suptitle("RMSE against DRAM bytes per frame (spp 4, 16, 64 along each line)", x=0.01, ha="left")
    data, _ = sr.render(fig, "real-frames")
    with open(path, "wb") as f:
        f.write(data)


def main(argv):
    args = argv[1:]
    opts = {"--spp": "16", "--markdown": None, "--plot": None, "--design": None, "--methods": None}
    pos = []
    while args:
        a = args.pop(0)
        if a in opts and args:
            opts[a] = args.pop(0)
        elif a.startswith("-"):
            print(__doc__.strip(), file=sys.stderr)
            return 2
        else:
            pos.append(a)
    if not pos:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    frames, params = [], []
    for d in pos:
        try:
            _, _, df, ps = sr.load(d)
        except sr.StudyError as e:
            print(f"real_frames: error: {d}: {e}", file=sys.stderr)
            return 1
        frames.append(df)
        params += [p for p in ps if p not in params]
    df = pd.concat(frames, ignore_index=True, sort=False)
    m, _ = sr.against_blend_frame(df, params)
    if m is None or m.empty:
        print(f"real_frames: error: {pos[0]}: no method has a blend point to compare with", file=sys.stderr)
        return 1
    t = m
    if opts["--design"] and "design" in t.columns:
        t = t[t["design"].map(design_name) == opts["--design"]]
    if opts["--methods"]:
        keep = {"blend"} | set(opts["--methods"].split(","))
        t = t[t["method"].astype(str).isin(keep)]
    if t.empty:
        print(f"real_frames: error: {pos[0]}: no point of design {opts['--design']} and methods {opts['--methods']}",
              file=sys.stderr)
        return 1
    text = ("### The frames\n\n" + frames_table(df) + f"\n### Every method against blend at {opts['--spp']} spp\n\n"
            + methods_table(t, float(opts["--spp"])) + "\n### The marginal cost over blend\n\n" + answer_table(t))
    if opts["--markdown"]:
        sr.write_atomically(opts["--markdown"], text)
    else:
        sys.stdout.write(text)
    if opts["--plot"]:
        plot(m, opts["--plot"])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
