#!/usr/bin/python3
"""Writes the report of a study folder: DIR/report/index.html and DIR/report/summary.md.

usage: study_report.py DIR

DIR is the folder of `ropsim study run` (results.db, study.toml, points/, refs/).
index.html is self-contained: the CSS is inline and every plot and image is a
base64 data URI, so it can be mailed or archived alone. summary.md holds the
same tables in Markdown. Both are written to a temporary file in DIR/report
and renamed, so a reader never sees a partial report. Sections (docs/studies.md
"The report"): points and failures; quality against cost with the Pareto
front; every swept numeric parameter against the key metrics; bottlenecks and
cycles by activity; image strips with error heat maps.

Runs on /usr/bin/python3 with Debian's python3-pandas, python3-numpy and
python3-matplotlib (Agg backend). `ropsim study report DIR` runs it.
"""
import base64
import html
import io
import json
import os
import sqlite3
import stat
import sys
import tempfile
import urllib.parse

try:
    import tomllib
except ImportError:  # Python < 3.11: the parameters come from params.json alone
    tomllib = None

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

RMSE = "vs_reference.rmse_8bit"
CYCLES = "timing.total_cycles"
DRAM_R, DRAM_W = "timing.dram.bytes_read", "timing.dram.bytes_written"
STATE_R, STATE_W = "counters.state_bytes_read", "counters.state_bytes_written"
SAMPLES = "counters.samples_written"
BOTTLENECK = "timing.bottleneck"
ACTIVITIES = ["busy", "idle", "input_starved", "output_blocked", "pixel_hazard", "memory"]
# Columns of the results table that are not parameters or metrics.
BOOKKEEPING = {"point", "point_index", "status", "error", "report", "reference_key"}


class StudyError(Exception):
    """The folder is not a study folder (one-line message)."""


# ---------------------------------------------------------------- loading


def load(study_dir):
    """Returns (name, points declared, results DataFrame, parameter names)."""
    if not os.path.isdir(study_dir):
        raise StudyError("no such folder")
    db_path = os.path.join(study_dir, "results.db")
    if not os.path.isfile(db_path):
        raise StudyError("not a study folder (no results.db)")
    try:
        uri = "file:" + urllib.parse.quote(os.path.abspath(db_path)) + "?mode=ro"
        con = sqlite3.connect(uri, uri=True)
        try:
            tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            if "results" not in tables:
                raise StudyError("results.db has no table 'results'")
            meta = {}
            if "study" in tables:
                meta = {str(k): str(v) for k, v in con.execute("SELECT key, value FROM study")}
            df = pd.read_sql_query("SELECT * FROM results", con)
        finally:
            con.close()
    except sqlite3.Error as e:
        raise StudyError(f"results.db: {e}") from None
    for c in ("point", "status"):
        if c not in df.columns:
            raise StudyError(f"results.db: table 'results' has no column '{c}'")
    if "point_index" in df.columns:
        df = df.sort_values("point_index", kind="stable").reset_index(drop=True)
    name = meta.get("name") or os.path.basename(os.path.normpath(study_dir))
    try:
        declared = int(meta.get("points", len(df)))
    except ValueError:
        declared = len(df)
    return name, declared, df, parameter_names(study_dir, df)


def parameter_names(study_dir, df):
    """The swept parameters: input, then the study file's axes (or the keys of
    the points' params.json), in their order, that are columns."""
    names = ["input"]
    axes = []
    toml_path = os.path.join(study_dir, "study.toml")
    if tomllib and os.path.isfile(toml_path):
        try:
            with open(toml_path, "rb") as f:
                axes = list(tomllib.load(f).get("axes", {}).keys())
        except (OSError, ValueError):
            axes = []
    if not axes:
        for h in df["point"]:
            try:
                with open(os.path.join(study_dir, "points", str(h), "params.json")) as f:
                    axes += [k for k in json.load(f) if k not in axes]
            except (OSError, ValueError):
                continue
    names += [a for a in axes if a not in names]
    return [n for n in names if n in df.columns and n not in BOOKKEEPING]


def num(df, col):
    """A column as floats (NaN where missing or not numeric)."""
    if col not in df.columns:
        return pd.Series(np.nan, index=df.index, dtype=float)
    return pd.to_numeric(df[col], errors="coerce")


def is_cycle(df):
    if "fidelity" in df.columns:
        return df["fidelity"].astype(str) == "cycle"
    return num(df, CYCLES).notna()


def varying(df, params, exclude=()):
    return [p for p in params if p not in exclude and df[p].nunique(dropna=True) > 1]


def fmt_value(v):
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return ""
    if isinstance(v, (float, np.floating)):
        return f"{v:.6g}" if v != int(v) or abs(v) >= 1e15 else str(int(v))
    if isinstance(v, (np.integer,)):
        return str(int(v))
    return str(v)


def params_text(row, params):
    return ", ".join(f"{p}={fmt_value(row[p])}" for p in params if p in row.index and fmt_value(row[p]) != "")


# ---------------------------------------------------------------- output pieces


class Report:
    """Collects the HTML body and the Markdown summary side by side."""

    def __init__(self):
        self.html, self.md, self.images = [], [], 0

    def heading(self, level, text, anchor=None):
        a = f' id="{html.escape(anchor)}"' if anchor else ""
        self.html.append(f"<h{level}{a}>{html.escape(text)}</h{level}>")
        self.md.append("#" * level + " " + text + "\n")

    def para(self, text):
        self.html.append(f"<p>{html.escape(text)}</p>")
        self.md.append(text + "\n")

    def table(self, header, rows, caption=None):
        if caption:
            self.html.append(f'<p class="caption">{html.escape(caption)}</p>')
            self.md.append(caption + "\n")
        h = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(fmt_value(v))}</td>" for v in r) + "</tr>" for r in rows)
        self.html.append(f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>")

        def cell(v):
            return fmt_value(v).replace("|", "\\|").replace("\n", " ")

        self.md.append("| " + " | ".join(cell(c) for c in header) + " |")
        self.md.append("|" + "|".join("---" for _ in header) + "|")
        for r in rows:
            self.md.append("| " + " | ".join(cell(v) for v in r) + " |")
        self.md.append("")

    def figure(self, fig, alt):
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=96)
        plt.close(fig)
        self.image_bytes(buf.getvalue(), alt)

    def image_bytes(self, data, alt):
        uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
        self.html.append(f'<figure><img src="{uri}" alt="{html.escape(alt)}"><figcaption>{html.escape(alt)}'
                         "</figcaption></figure>")
        self.md.append(f"*Figure in index.html: {alt}*\n")
        self.images += 1


CSS = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1200px; color: #222; line-height: 1.4; }
h1 { border-bottom: 2px solid #446; padding-bottom: .2em; }
h2 { border-bottom: 1px solid #aab; margin-top: 2em; }
table { border-collapse: collapse; margin: .5em 0 1em; font-size: 90%; }
th, td { border: 1px solid #ccd; padding: .2em .6em; text-align: left; }
th { background: #eef; }
tr:nth-child(even) td { background: #f8f8fc; }
figure { margin: 1em 0; }
figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption, .caption { font-size: 90%; color: #555; }
"""

# For the browser test, and for a reader's console: a resource that fails to
# load is logged as "resource failed to load: URL" (the report has none: every
# image is a data URI), and once the page has loaded, the number of images the
# browser decoded is set as data-images-decoded on <body>. Inline, no resource.
SCRIPT = """
window.addEventListener('error', function (e) {
  var t = e.target;
  if (t && t !== window) console.error('resource failed to load: ' + (t.src || t.href || t.tagName));
}, true);
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.body.setAttribute('data-images-decoded', String(ok));
});
"""


def new_file_mode(path):
    """The mode the file written to path gets: a replaced file's own, else
    what open() would give a new file (0666 less the umask), as ropsim's
    writer does (docs/outputs.md); mkstemp alone would leave 0600."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except FileNotFoundError:
        mask = os.umask(0o22)
        os.umask(mask)
        return 0o666 & ~mask


def write_atomically(path, text):
    d = os.path.dirname(path)
    mode = new_file_mode(path)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", dir=d)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fchmod(f.fileno(), mode)
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


# ---------------------------------------------------------------- sections


def section_points(rep, name, declared, df, params):
    ok = int((df["status"] == "ok").sum())
    failed = int((df["status"] != "ok").sum())
    rep.heading(2, "Points", "points")
    missing = max(0, declared - len(df))
    text = f"{declared} points: {ok} ok, {failed} failed"
    if missing:
        text += f", {missing} not run yet"
    rep.para(text + ".")
    rep.table(["parameter", "values"],
              [[p, ", ".join(fmt_value(v) for v in pd.unique(df[p].dropna()))] for p in params],
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
    for fidelity, col, what, sub in plots:
        sub = sub[sub[col].notna()]
        if sub.empty:
            continue
        inputs = list(pd.unique(sub["input"])) if "input" in sub.columns else [None]
        keys = curve_key(params, sub)
        fig, axes = plt.subplots(1, len(inputs), figsize=(5.2 * len(inputs), 4.2), squeeze=False)
        for ax, inp in zip(axes[0], inputs):
            s = sub if inp is None else sub[sub["input"] == inp]
            group_cols = keys + (["spp"] if "spp" in s.columns else [])
            # Several points per curve and spp (seeds, fidelities): their mean.
            agg = s.groupby(group_cols, dropna=False)[[col, "_rmse"]].mean().reset_index() if group_cols else s
            if keys:
                groups = agg.groupby(keys if len(keys) > 1 else keys[0], sort=False)
            else:
                groups = [((), agg)]
            for gk, g in groups:
                g = g.sort_values("spp") if "spp" in g.columns else g
                ax.plot(g[col], g["_rmse"], "o-", label=label_of(keys, gk), ms=5)
                if "spp" in g.columns:
                    for _, r in g.iterrows():
                        ax.annotate(fmt_value(r["spp"]), (r[col], r["_rmse"]), textcoords="offset points",
                                    xytext=(4, 4), fontsize=7)
            c, e = agg[col].to_numpy(float), agg["_rmse"].to_numpy(float)
            front = pareto(c, e)
            ax.step(c[front], e[front], where="post", color="k", lw=1, ls="--", alpha=.6)
            ax.plot(c[front], e[front], "o", ms=11, mfc="none", mec="k", label="Pareto front")
            for i in front:
                r = agg.iloc[i]
                pareto_rows.append([fidelity, fmt_value(inp), label_of(keys, tuple(r[k] for k in keys)),
                                    fmt_value(r["spp"]) if "spp" in agg.columns else "", what, c[i], e[i]])
            ax.set_xscale("log" if c.min() > 0 and c.max() / c.min() > 20 else "linear")
            ax.set_xlabel(what)
            ax.set_ylabel("RMSE (8-bit)")
            ax.set_title(f"{inp}" if inp is not None else "all inputs", fontsize=10)
            ax.grid(alpha=.3)
            ax.legend(fontsize=7)
        fig.suptitle(f"RMSE against {what} ({fidelity} points; numbers: spp)", fontsize=11)
        fig.tight_layout()
        rep.figure(fig, f"RMSE against {what}, {fidelity} points, one curve per method, spp annotated, "
                        "Pareto front circled")
    if pareto_rows:
        rep.table(["fidelity", "input", "curve", "spp", "cost", "cost value", "RMSE"], pareto_rows,
                  caption="The Pareto front: points no other point of the same input beats in both cost and RMSE.")


def section_equal_quality(rep, df, params):
    """For target RMSEs, the smallest spp at which each curve reaches them and its cost there."""
    rep.heading(2, "Equal quality", "equal-quality")
    ok = df[(df["status"] == "ok")].copy()
    ok["_rmse"] = num(ok, RMSE)
    ok = ok[ok["_rmse"].notna()]
    if ok.empty or "spp" not in ok.columns or ok["spp"].nunique() < 2:
        rep.para("The equal-quality table needs an RMSE against a reference and at least two spp values.")
        return
    cyc = is_cycle(ok)
    ok["_dram"] = num(ok, DRAM_R) + num(ok, DRAM_W)
    ok["_state"] = num(ok, STATE_R) + num(ok, STATE_W)
    ok["_cycles"] = num(ok, CYCLES)
    sub, costs = (ok[cyc], [("_cycles", "cycles"), ("_dram", "DRAM bytes")]) if cyc.any() else \
        (ok[~cyc], [("_state", "state bytes")])
    keys = curve_key(params, sub)
    rows = []
    inputs = list(pd.unique(sub["input"])) if "input" in sub.columns else [None]
    for inp in inputs:
        s = sub if inp is None else sub[sub["input"] == inp]
        agg = s.groupby(keys + ["spp"], dropna=False)[["_rmse"] + [c for c, _ in costs]].mean().reset_index()
        best = agg.groupby("spp")["_rmse"].min().sort_index()
        # The targets: what the best curve reaches at each spp (rounded up a little).
        targets = sorted({float(f"{v * 1.02:.3g}") for v in best.to_numpy(float)}, reverse=True)[:6]
        groups = agg.groupby(keys if len(keys) > 1 else keys[0], sort=False) if keys else [((), agg)]
        for t in targets:
            for gk, g in groups:
                g = g.sort_values("spp")
                hit = g[g["_rmse"] <= t]
                label = label_of(keys, gk)
                if hit.empty:
                    rows.append([fmt_value(inp), t, label, "not reached", round(float(g["_rmse"].min()), 3)] +
                                ["" for _ in costs])
                else:
                    r = hit.iloc[0]
                    rows.append([fmt_value(inp), t, label, fmt_value(r["spp"]), round(float(r["_rmse"]), 3)] +
                                [int(round(float(r[c]))) for c, _ in costs])
    fidelity = "cycle" if cyc.any() else "functional"
    rep.table(["input", "target RMSE", "curve", "spp", "RMSE there"] + [w for _, w in costs], rows,
              caption=f"For each target RMSE (8-bit units; what the best curve reaches at each spp), the smallest "
                      f"spp at which each curve reaches it and its cost there ({fidelity} points, means over the "
                      f"other parameters); \"not reached\" gives the curve's best RMSE.")


SILICON_ROP = "silicon.per_rop.nand2_eq"
KEY_METRICS = [(RMSE, "RMSE (8-bit)"), ("vs_reference.bias_8bit", "bias (8-bit, signed)"), (CYCLES, "total cycles"),
               ("_dram", "DRAM bytes"), (SAMPLES, "samples written"), (SILICON_ROP, "NAND2 eq., LK units of a ROP")]


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
                       f"RMSE against {p}, gates against {p}, RMSE against gates{tag}")
            shown += 1
    if not shown:
        rep.para("The silicon cost is the same at every point: no swept parameter changes it.")


def section_axes(rep, df, params):
    rep.heading(2, "Parameters against metrics", "axes")
    ok = df[df["status"] == "ok"].copy()
    ok["_dram"] = num(ok, DRAM_R) + num(ok, DRAM_W)
    numeric = [p for p in params if p != "input" and pd.to_numeric(ok[p], errors="coerce").notna().all()
               and ok[p].nunique() > 1] if not ok.empty else []
    if not numeric:
        rep.para("No swept numeric parameter has more than one value among the points that ran, so there is no "
                 "parameter-against-metric plot.")
        return
    metrics = [(c, t) for c, t in KEY_METRICS if num(ok, c).notna().any()]
    has_method = "method" in ok.columns
    inputs = list(pd.unique(ok["input"])) if "input" in ok.columns else [None]
    styles = ["-", "--", ":", "-."]  # one per input; the colour is the method's
    methods = list(pd.unique(ok["method"])) if has_method else []
    colours = plt.get_cmap("tab10")
    for p in numeric:
        fig, axes = plt.subplots(1, len(metrics), figsize=(4.2 * len(metrics), 3.6), squeeze=False)
        for ax, (col, title) in zip(axes[0], metrics):
            for ii, inp in enumerate(inputs):
                s = ok if inp is None else ok[ok["input"] == inp]
                s = s.assign(_x=pd.to_numeric(s[p]), _y=num(s, col))
                s = s[s["_y"].notna()]
                if s.empty:
                    continue
                for m, g in (s.groupby("method", sort=False) if has_method else [("points", s)]):
                    g = g.groupby("_x")["_y"].mean()
                    lab = f"{m}" + (f" · {inp}" if len(inputs) > 1 else "")
                    colour = colours(methods.index(m) % 10) if m in methods else None
                    ax.plot(g.index, g.values, "o" + styles[ii % len(styles)], label=lab, ms=4, color=colour)
            ax.set_xlabel(p)
            ax.set_title(title, fontsize=10)
            ax.grid(alpha=.3)
            xs = pd.to_numeric(ok[p])
            if xs.min() > 0 and xs.max() / xs.min() >= 8:
                ax.set_xscale("log", base=2)
        axes[0][0].legend(fontsize=7)
        fig.suptitle(f"key metrics against {p} (mean over the other parameters)", fontsize=11)
        fig.tight_layout()
        rep.figure(fig, f"Key metrics against {p}, one line per method (and input)")


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
        rep.table([b] + list(ct.columns), [[i] + [int(v) for v in ct.loc[i]] for i in ct.index],
                  caption=f"Bottleneck class (timing.bottleneck before the ':') of the cycle points, counted per {b}.")
    key = by[0] if by else None
    if key:
        ct = pd.crosstab(cyc[key], cyc["_class"])
        fig, ax = plt.subplots(figsize=(max(5, 1.1 * len(ct) + 3), 3.8))
        bottom = np.zeros(len(ct))
        x = np.arange(len(ct))
        for c in ct.columns:
            ax.bar(x, ct[c].to_numpy(), bottom=bottom, label=c)
            bottom += ct[c].to_numpy()
        ax.set_xticks(x, [fmt_value(i) for i in ct.index])
        ax.set_xlabel(key)
        ax.set_ylabel("points")
        ax.legend(fontsize=7)
        ax.set_title(f"bottleneck class per {key}", fontsize=10)
        fig.tight_layout()
        rep.figure(fig, f"Bottleneck class of the cycle points per {key}")
    act = unit_activity(cyc)
    if act.empty:
        rep.para("The cycle points' reports hold no timing.units, so there is no breakdown by activity.")
        return
    totals = act.groupby("kind", sort=False)[ACTIVITIES].sum()
    rep.table(["unit kind"] + ACTIVITIES, [[k] + [int(v) for v in totals.loc[k]] for k in totals.index],
              caption="Cycles by activity summed per unit kind over every cycle point.")
    methods = list(pd.unique(act["method"]))
    fig, axes = plt.subplots(1, len(methods), figsize=(4.6 * len(methods), 4.2), squeeze=False, sharey=True)
    colours = plt.get_cmap("tab10")
    for ax, m in zip(axes[0], methods):
        t = act[act["method"] == m].groupby("kind", sort=False)[ACTIVITIES].sum()
        x = np.arange(len(t))
        bottom = np.zeros(len(t))
        for ai, a in enumerate(ACTIVITIES):
            ax.bar(x, t[a].to_numpy(), bottom=bottom, label=a, color=colours(ai))
            bottom += t[a].to_numpy()
        ax.set_xticks(x, list(t.index), rotation=40, ha="right", fontsize=7)
        ax.set_title(f"{m}", fontsize=10)
        ax.grid(alpha=.3, axis="y")
    axes[0][0].set_ylabel("cycles (summed over the points)")
    axes[0][-1].legend(fontsize=7)
    fig.suptitle("cycles by activity per unit kind", fontsize=11)
    fig.tight_layout()
    rep.figure(fig, "Cycles by activity per unit kind, stacked, one panel per method")


def read_rgb8(path):
    """An image file as an H x W x 3 array in 8-bit units."""
    a = mpimg.imread(path)
    if a.dtype != np.uint8:
        a = np.clip(a * 255.0, 0, 255)
    a = np.asarray(a, dtype=float)
    if a.ndim == 2:
        a = np.stack([a] * 3, axis=-1)
    return a[..., :3]


def section_images(rep, study_dir, df, params):
    rep.heading(2, "Image strips", "images")
    ok = df[df["status"] == "ok"].copy()
    if ok.empty or "input" not in ok.columns:
        rep.para("No point ran, so there is no image.")
        return
    ok["_img"] = [os.path.join(study_dir, "points", str(h), "image.png") for h in ok["point"]]
    ok = ok[[os.path.isfile(p) for p in ok["_img"]]]
    if ok.empty:
        rep.para("No point saved its image (set save_images = true under [study] and run the study again), "
                 "so there are no image strips.")
        return
    shown = 0
    for inp in pd.unique(ok["input"]):
        s = ok[ok["input"] == inp]
        spp = None
        if "spp" in s.columns and num(s, "spp").notna().any():
            spp = num(s, "spp").max()
            s = s[num(s, "spp") == spp]
        ref_path = None
        for k in s.get("reference_key", pd.Series(dtype=str)).dropna():
            p = os.path.join(study_dir, "refs", f"{k}.png")
            if k and os.path.isfile(p):
                ref_path = p
                break
        reps = s.groupby("method", sort=False).head(1) if "method" in s.columns else s.head(1)
        try:
            ref = read_rgb8(ref_path) if ref_path else None
            imgs = [(fmt_value(r.get("method", "image")), read_rgb8(r["_img"])) for _, r in reps.iterrows()]
        except (OSError, ValueError, SyntaxError) as e:
            rep.para(f"{inp}: an image cannot be read ({e}); no strip.")
            continue
        ncol = len(imgs) + (1 if ref is not None else 0)
        nrow = 2 if ref is not None else 1
        fig, axes = plt.subplots(nrow, ncol, figsize=(2.6 * ncol + 0.8, 2.7 * nrow), squeeze=False)
        title_spp = f" at {fmt_value(spp)} spp" if spp is not None else ""
        col = 0
        if ref is not None:
            axes[0][0].imshow(ref / 255.0, interpolation="nearest")
            axes[0][0].set_title("reference (A-buffer)", fontsize=9)
            axes[1][0].axis("off")
            axes[1][0].text(0.5, 0.5, "|image − reference|\nmean over RGB\n(8-bit units)", ha="center",
                            va="center", fontsize=8, transform=axes[1][0].transAxes)
            col = 1
        errs = []
        for i, (m, im) in enumerate(imgs):
            ax = axes[0][col + i]
            ax.imshow(np.clip(im / 255.0, 0, 1), interpolation="nearest")
            ax.set_title(m, fontsize=9)
            if ref is not None:
                if im.shape == ref.shape:
                    errs.append((i, np.abs(im - ref).mean(axis=-1)))
                else:
                    axes[1][col + i].text(0.5, 0.5, "size differs\nfrom the reference", ha="center", va="center",
                                          fontsize=8, transform=axes[1][col + i].transAxes)
        vmax = max([float(e.max()) for _, e in errs] + [1.0])
        last = None
        for i, e in errs:
            ax = axes[1][col + i]
            last = ax.imshow(e, cmap="inferno", vmin=0, vmax=vmax, interpolation="nearest")
            ax.set_title(f"error, mean {e.mean():.2f}", fontsize=8)
        for row in axes:
            for ax in row:
                ax.set_xticks([])
                ax.set_yticks([])
        if last is not None:
            fig.colorbar(last, ax=list(axes[1]), shrink=0.85, label="|error| (8-bit)")
        fig.suptitle(f"{inp}{title_spp}", fontsize=11)
        rep.figure(fig, f"{inp}{title_spp}: reference, each method's image and its error heat map")
        shown += 1
        if ref is None:
            rep.para(f"{inp}: the reference image is missing, so there is no error heat map.")
    if not shown:
        rep.para("No image strip could be drawn.")


# ---------------------------------------------------------------- main


def build(study_dir):
    name, declared, df, params = load(study_dir)
    rep = Report()
    rep.heading(1, f"Study {name}", "study")
    rep.para(f"Folder {os.path.abspath(study_dir)}; report of `ropsim study report` "
             "(analysis/study_report.py, docs/studies.md \"The report\").")
    section_points(rep, name, declared, df, params)
    section_quality(rep, df, params)
    section_equal_quality(rep, df, params)
    section_silicon(rep, df, params)
    section_axes(rep, df, params)
    section_bottlenecks(rep, df, params)
    section_images(rep, study_dir, df, params)
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>Study {html.escape(name)}</title><style>{CSS}</style><script>{SCRIPT}</script></head>\n"
            f"<body data-images=\"{rep.images}\">\n" + "\n".join(rep.html) + "\n</body></html>\n")
    out = os.path.join(study_dir, "report")
    os.makedirs(out, exist_ok=True)
    write_atomically(os.path.join(out, "index.html"), page)
    write_atomically(os.path.join(out, "summary.md"), "\n".join(rep.md) + "\n")
    return out, rep.images


def main(argv):
    if len(argv) != 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 0 if len(argv) == 2 else 2
    study_dir = argv[1]
    try:
        out, n = build(study_dir)
    except StudyError as e:
        print(f"study_report: error: {study_dir}: {e}", file=sys.stderr)
        return 1
    except OSError as e:
        print(f"study_report: error: {study_dir}: {e.strerror or e}: {e.filename or ''}".rstrip(": "),
              file=sys.stderr)
        return 1
    print(f"wrote {os.path.join(out, 'index.html')} ({n} figures) and {os.path.join(out, 'summary.md')}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
