#!/usr/bin/python3
"""Writes the report of a study folder: DIR/report/index.html and DIR/report/summary.md.

usage: study_report.py DIR [--out OUT]

--out OUT writes OUT/index.html and OUT/summary.md instead (a study on
read-only media: the script only reads DIR).

DIR is the folder of `ropsim study run` (results.db, study.toml, points/, refs/).
index.html is self-contained: the CSS is inline and every plot and image is a
base64 data URI, so it can be mailed or archived alone. summary.md holds the
same tables in Markdown. Both are written to a temporary file in DIR/report
and renamed, so a reader never sees a partial report. Sections (docs/studies.md
"The report"): points and failures; quality against cost with the Pareto
front; equal quality; against blend (a study with the method blend);
quality against silicon; every swept parameter against
the key metrics; the fidelities against the cycle model (a study of more than
one); bottlenecks and cycles by activity; image strips with error heat maps.

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
import matplotlib.text as mtext  # noqa: E402
from matplotlib import cm, colors, ticker  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fidelity  # noqa: E402

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
                axes_table = tomllib.load(f).get("axes", {})
        except (OSError, ValueError):
            axes_table = {}
        # Named cases are one axis: its name (column "case"), then the keys
        # the cases set, in the order they first appear.
        for key, value in axes_table.items():
            if key != "cases":
                axes.append(key)
                continue
            axes.append("case")
            for case in value if isinstance(value, list) else []:
                if isinstance(case, dict):
                    axes += [k for k in case if k != "name" and k not in axes]
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


# ---------------------------------------------------------------- figures
#
# Every figure is drawn for the page at 100 % zoom: DPI pixels per inch, at
# most PAGE_WIDTH_IN wide (the page's column is wider, so no figure is scaled
# down), text at least MIN_TEXT_PT (10 px at 96 dpi). Legends sit in a column
# of their own beside the panels, never on the data; a linear axis has plain
# tick labels (k, M, G suffixes; no offset or multiplier text); an axis whose
# values span a decade or more is logarithmic. Each figure's <img> carries the
# layout it was drawn with (data-layout: the bounding boxes of its texts,
# axes, legends and data points in pixels of the PNG, the font sizes, the
# offset texts), which the tests check.

DPI = 96
PAGE_WIDTH_IN = 13.0
MIN_TEXT_PT = 8.0
LEGEND_WIDTH_IN = 2.7

plt.rcParams.update({
    "font.size": 10.5, "axes.titlesize": 11.5, "axes.labelsize": 10.5, "xtick.labelsize": 10, "ytick.labelsize": 10,
    "legend.fontsize": 10, "figure.titlesize": 12.5, "axes.formatter.useoffset": False, "figure.dpi": DPI,
    "savefig.dpi": DPI, "axes.titlelocation": "left",
})


def short_number(v, _pos=None):
    """A tick label: 318k, 1.2M, 3G, 0.25 (no offset, no multiplier)."""
    a = abs(v)
    for div, suffix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if a >= 10 * div or (a >= div and suffix != "k"):
            return f"{v / div:.3g}{suffix}"
    return f"{v:.3g}" if v != int(v) else str(int(v))


def spans_decade(values):
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], dtype=float)
    return len(v) > 1 and v.min() > 0 and v.max() / v.min() >= 10


def plain_ticks(ax):
    """Plain tick labels on the linear axes of ax (and of its secondary axes)."""
    axes = [ax] + [c for c in getattr(ax, "child_axes", [])]
    for a in axes:
        if hasattr(a, "_set_scale"):
            a._set_scale()  # a secondary axis takes its parent's scale now, not at the draw (which would reset it)
        for axis in (a.xaxis, a.yaxis):
            if axis.get_scale() in ("linear", "function") and isinstance(axis.get_major_formatter(),
                                                                        ticker.ScalarFormatter):
                axis.set_major_formatter(ticker.FuncFormatter(short_number))
            elif axis.get_scale() in ("log", "functionlog") and not isinstance(axis.get_major_locator(),
                                                                             ticker.FixedLocator):
                lo, hi = sorted(axis.get_view_interval())
                if lo > 0 and hi / lo < 3:
                    axis.set_major_locator(ticker.MaxNLocator(4))
                elif lo > 0 and hi / lo < 100:
                    axis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
                axis.set_major_formatter(ticker.FuncFormatter(short_number))
                axis.set_minor_formatter(ticker.NullFormatter())


def thin_ticks(fig):
    """Drops the tick labels that would overlap their neighbours (with a 4 px
    gap), after a first draw has placed them: an axis keeps every k-th label
    for the smallest k whose labels are clear of each other. An axis whose
    ticks the figure fixed (categories) is left as it is."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        if not ax.axison:
            continue
        for axis, lo_of, hi_of in ((ax.xaxis, "x0", "x1"), (ax.yaxis, "y0", "y1")):
            if isinstance(axis.get_major_locator(), ticker.FixedLocator):
                continue
            v0, v1 = sorted(axis.get_view_interval())
            ticks = [(t.get_loc(), t.label1) for t in axis.get_major_ticks()
                     if t.label1.get_visible() and t.label1.get_text().strip() and v0 <= t.get_loc() <= v1]
            if len(ticks) < 2:
                continue
            spans = sorted((getattr(lab.get_window_extent(renderer), lo_of),
                            getattr(lab.get_window_extent(renderer), hi_of), loc) for loc, lab in ticks)
            for step in range(1, len(spans) + 1):
                kept = spans[::step]
                if all(b[0] >= a[1] + 4 for a, b in zip(kept, kept[1:])):
                    break
            kept = [loc for _, _, loc in kept]
            if len(kept) < len(spans):
                fmt = axis.get_major_formatter()
                axis.set_major_locator(ticker.FixedLocator(kept))
                axis.set_major_formatter(fmt)


def panel_grid(n, ncols, panel_w=3.4, panel_h=2.9, legend=True, sharey=False):
    """A figure of n panels in rows of ncols and, with legend, a column at the
    right for the legend. Returns (figure, panels, legend axes or None)."""
    ncols = max(1, min(n, ncols))
    nrows = (n + ncols - 1) // ncols
    leg = LEGEND_WIDTH_IN if legend else 0.0
    panel_w = min(panel_w, (PAGE_WIDTH_IN - leg) / ncols)
    fig = plt.figure(figsize=(ncols * panel_w + leg, nrows * panel_h + 0.5), dpi=DPI, layout="constrained")
    gs = fig.add_gridspec(nrows, ncols + (1 if legend else 0),
                          width_ratios=[panel_w] * ncols + ([leg] if legend else []))
    axes = []
    for i in range(n):
        share = axes[0] if sharey and axes else None
        axes.append(fig.add_subplot(gs[i // ncols, i % ncols], sharey=share))
    lax = None
    if legend:
        lax = fig.add_subplot(gs[:, ncols])
        lax.axis("off")
    return fig, axes, lax


def put_legend(lax, axes, title=None):
    """The legend of every labelled artist of axes (each label once) in the
    legend axes lax, at its top left."""
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels and not lab.startswith("_"):
                handles.append(h)
                labels.append(lab)
    if handles:
        lax.legend(handles, labels, loc="upper left", borderaxespad=0, frameon=False, title=title,
                   alignment="left")


def _box(bb, height):
    return [round(float(bb.x0), 1), round(float(height - bb.y1), 1), round(float(bb.x1), 1),
            round(float(height - bb.y0), 1)]


def render(fig, name):
    """The figure as PNG bytes and its layout (see the comment above)."""
    drawn = []
    draw = mtext.Text.draw

    def recording(self, renderer):
        draw(self, renderer)
        if self.get_visible() and self.get_text().strip():
            drawn.append(self)

    for ax in fig.axes:
        plain_ticks(ax)
    thin_ticks(fig)
    mtext.Text.draw = recording
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    finally:
        mtext.Text.draw = draw
    renderer = fig.canvas.get_renderer()
    width, height = fig.canvas.get_width_height()
    in_legend = {id(x) for lg in [a.get_legend() for a in fig.axes] + list(fig.legends) if lg is not None
                 for x in lg.findobj(mtext.Text)}
    texts, seen = [], set()
    for t in drawn:
        if id(t) in seen:
            continue
        seen.add(id(t))
        kind = "annotation" if isinstance(t, mtext.Annotation) else "legend" if id(t) in in_legend else "layout"
        texts.append({"text": t.get_text(), "px": round(t.get_fontsize() * DPI / 72.0, 2), "kind": kind,
                      "bbox": _box(t.get_window_extent(renderer), height)})
    axes, legends = [], []
    for ax in fig.axes:
        if ax.get_legend() is not None:
            legends.append(_box(ax.get_legend().get_window_extent(renderer), height))
        if not ax.axison:
            continue
        pts = []
        for line in ax.get_lines():
            if line.get_marker() in (None, "", "None", " ") and line.get_linestyle() in ("None", "", " "):
                continue
            xy = np.asarray(line.get_xydata(), dtype=float)
            xy = xy[np.isfinite(xy).all(axis=1)] if len(xy) else xy
            if len(xy):
                pts += ax.transData.transform(xy).tolist()
        for c in ax.collections:
            off = np.asarray(c.get_offsets(), dtype=float)
            if len(off) and off.ndim == 2:
                off = off[np.isfinite(off).all(axis=1)]
                pts += c.get_offset_transform().transform(off).tolist()
        for p in ax.patches:
            bb = p.get_window_extent(renderer)
            if bb.width > 0 and bb.height > 0:
                pts += [[bb.x0, bb.y0], [bb.x1, bb.y1], [(bb.x0 + bb.x1) / 2, (bb.y0 + bb.y1) / 2]]
        axb = ax.get_window_extent(renderer)
        inside = [[round(x, 1), round(height - y, 1)] for x, y in pts
                  if axb.x0 - 1 <= x <= axb.x1 + 1 and axb.y0 - 1 <= y <= axb.y1 + 1]
        axes.append({"bbox": _box(axb, height), "title": ax.get_title(loc="left") or ax.get_title(),
                     "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(), "xscale": ax.get_xscale(),
                     "yscale": ax.get_yscale(),
                     "offset_text": [ax.xaxis.get_offset_text().get_text(), ax.yaxis.get_offset_text().get_text()],
                     "xticklabels": [t.get_text() for t in ax.get_xticklabels() if t.get_text()],
                     "points": inside})
    for lg in fig.legends:
        legends.append(_box(lg.get_window_extent(renderer), height))
    plt.close(fig)
    return buf.getvalue(), {"figure": name, "width": width, "height": height, "dpi": DPI, "texts": texts,
                            "axes": axes, "legends": legends}


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

    def img(self, data, alt, attrs=None, width=None, height=None):
        """An <img> of PNG bytes as a data URI, with attrs as data-* attributes."""
        uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
        extra = "".join(f' {k}="{html.escape(str(v))}"' for k, v in (attrs or {}).items())
        size = (f' width="{int(width)}"' if width else "") + (f' height="{int(height)}"' if height else "")
        self.images += 1
        return f'<img src="{uri}" alt="{html.escape(alt)}"{size}{extra}>'

    def figure(self, fig, alt, name):
        """A matplotlib figure, with its layout (render()) in data-layout."""
        data, layout = render(fig, name)
        tag = self.img(data, alt, {"data-figure": name, "data-layout": json.dumps(layout, separators=(",", ":"))},
                       layout["width"], layout["height"])
        self.html.append(f'<figure class="plot">{tag}<figcaption>{html.escape(alt)}</figcaption></figure>')
        self.md.append(f"*Figure in index.html: {alt}*\n")

    def raw(self, text_html, md=None):
        self.html.append(text_html)
        if md:
            self.md.append(md + "\n")


CSS = """
body { font-family: sans-serif; margin: 1.5em auto; max-width: 1300px; padding: 0 16px; color: #222;
       line-height: 1.4; }
h1 { border-bottom: 2px solid #446; padding-bottom: .2em; }
h2 { border-bottom: 1px solid #aab; margin-top: 2em; }
table { border-collapse: collapse; margin: .5em 0 1em; font-size: 90%; }
th, td { border: 1px solid #ccd; padding: .2em .6em; text-align: left; }
th { background: #eef; }
tr:nth-child(even) td { background: #f8f8fc; }
figure { margin: 1em 0; }
figure.plot img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption, .caption { font-size: 90%; color: #555; }
.strip { display: flex; flex-wrap: wrap; gap: 12px; align-items: flex-start; margin: .5em 0 1.5em; }
.strip figure { margin: 0; display: flex; flex-direction: column; gap: 4px; }
.strip img { image-rendering: pixelated; border: 1px solid #ddd; }
.strip figcaption { max-width: 200px; color: #222; }
.strip figcaption .params { color: #555; display: block; }
"""

# For the browser test, and for a reader's console: a resource that fails to
# load is logged as "resource failed to load: URL" (the report has none: every
# image is a data URI), and once the page has loaded, the number of images the
# browser decoded is set as data-images-decoded on <body>, and each image's
# shown box inside its border (CSS pixels) as data-shown="left top width
# height". Inline, no resource.
SCRIPT = """
window.addEventListener('error', function (e) {
  var t = e.target;
  if (t && t !== window) console.error('resource failed to load: ' + (t.src || t.href || t.tagName));
}, true);
window.addEventListener('load', function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  imgs.forEach(function (i) {
    var r = i.getBoundingClientRect();
    i.setAttribute('data-shown', [r.left + window.scrollX + i.clientLeft, r.top + window.scrollY + i.clientTop,
                                  i.clientWidth, i.clientHeight]
      .map(function (v) { return v.toFixed(1); }).join(' '));
  });
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


def sorted_values(series):
    """The distinct values of a parameter: numerically sorted when they are
    all numbers, else in the order of the points."""
    vals = list(pd.unique(series.dropna()))
    nums = pd.to_numeric(pd.Series(vals, dtype=object), errors="coerce")
    if len(vals) and nums.notna().all():
        return [v for _, v in sorted(zip(nums, vals), key=lambda p: p[0])]
    return vals


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


# ---------------------------------------------------------------- against blend

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


def read_rgb8(path):
    """An image file as an H x W x 3 array in 8-bit units."""
    a = mpimg.imread(path)
    if a.dtype != np.uint8:
        a = np.clip(a * 255.0, 0, 255)
    a = np.asarray(a, dtype=float)
    if a.ndim == 2:
        a = np.stack([a] * 3, axis=-1)
    return a[..., :3]


def png_bytes(rgb):
    """An H x W x 3 (or 4) array in [0, 1] as PNG bytes."""
    buf = io.BytesIO()
    mpimg.imsave(buf, np.clip(rgb, 0, 1), format="png", metadata={"Software": None})
    return buf.getvalue()


ERROR_CMAP = "inferno"


def error_colour_bar(vmax):
    fig = plt.figure(figsize=(2.1, 1.05), dpi=DPI, layout="constrained")
    ax = fig.add_subplot()
    cb = fig.colorbar(cm.ScalarMappable(norm=colors.Normalize(0, vmax), cmap=ERROR_CMAP), cax=ax,
                      orientation="horizontal")
    cb.set_label("|error| (8-bit units)")
    cb.ax.xaxis.set_major_locator(ticker.MaxNLocator(4))
    return fig


def section_images(rep, study_dir, df, params):
    """For each input at its largest spp: the reference, and per method one
    point's image with its error heat map under it, both in one <figure>
    whose caption, data-point, data-method and data-spp come from that
    point's row."""
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
    others = [p for p in varying(ok, params, exclude=("input", "method", "spp"))]
    for inp in pd.unique(ok["input"]):
        s = ok[ok["input"] == inp]
        spp = None
        if "spp" in s.columns and num(s, "spp").notna().any():
            spp = num(s, "spp").max()
            s = s[num(s, "spp") == spp]
        ref_path = ref_key = None
        for k in s.get("reference_key", pd.Series(dtype=str)).dropna():
            p = os.path.join(study_dir, "refs", f"{k}.png")
            if k and os.path.isfile(p):
                ref_path, ref_key = p, k
                break
        chosen = s.groupby("method", sort=False).head(1) if "method" in s.columns else s.head(1)
        try:
            ref = read_rgb8(ref_path) if ref_path else None
            points = [(r, read_rgb8(r["_img"])) for _, r in chosen.iterrows()]
        except (OSError, ValueError, SyntaxError) as e:
            rep.para(f"{inp}: an image cannot be read ({e}); no strip.")
            continue
        errs = [np.abs(im - ref).mean(axis=-1) if ref is not None and im.shape == ref.shape else None
                for _, im in points]
        vmax = max([float(e.max()) for e in errs if e is not None] + [1.0])
        title_spp = f" at {fmt_value(spp)} spp" if spp is not None else ""
        rep.heading(3, f"{inp}{title_spp}", f"images-{inp}")
        tiles = []
        width = (ref if ref is not None else points[0][1]).shape[1]
        scale = max(1, 192 // max(1, width))

        def tag(data, im, alt, attrs):
            return rep.img(data, alt, attrs, im.shape[1] * scale, im.shape[0] * scale)

        if ref is not None:
            bar_data, bar_layout = render(error_colour_bar(vmax), f"images:{inp}:colour-bar")
            tiles.append(
                f'<figure data-role="reference" data-key="{html.escape(str(ref_key))}">'
                + tag(png_bytes(ref / 255.0), ref, f"{inp}: reference (A-buffer)", {"data-role": "reference"})
                + rep.img(bar_data, "colour bar of the error maps",
                          {"data-role": "colour-bar", "data-figure": bar_layout["figure"],
                           "data-layout": json.dumps(bar_layout, separators=(",", ":"))},
                          bar_layout["width"], bar_layout["height"])
                + "<figcaption>reference (A-buffer); the error maps' scale: |image − reference|, the mean "
                  "over R, G, B</figcaption></figure>")
        cmap = plt.get_cmap(ERROR_CMAP)
        for (r, im), e in zip(points, errs):
            method = fmt_value(r.get("method", "image"))
            point_spp = fmt_value(r["spp"]) if "spp" in r.index else ""
            label = method + (f", {point_spp} spp" if point_spp else "")
            extra = params_text(r, others)
            attrs = {"data-point": r["point"], "data-method": method, "data-spp": point_spp}
            with open(r["_img"], "rb") as f:
                own = f.read()
            body = tag(own, im, f"{inp}: {label}", dict(attrs, **{"data-role": "image"}))
            cap = html.escape(label)
            if e is not None:
                body += tag(png_bytes(cmap(e / vmax)[..., :3]), im, f"{inp}: {label}: error heat map",
                            dict(attrs, **{"data-role": "error"}))
                cap += f"<br>mean |error| {e.mean():.2f}"
            elif ref is not None:
                cap += "<br>size differs from the reference: no error map"
            if extra:
                cap += f'<span class="params">{html.escape(extra)}</span>'
            tiles.append(f'<figure data-point="{html.escape(str(r["point"]))}" data-method="{html.escape(method)}" '
                         f'data-spp="{html.escape(point_spp)}">{body}<figcaption>{cap}</figcaption></figure>')
        rep.raw(f'<div class="strip" data-input="{html.escape(str(inp))}">' + "".join(tiles) + "</div>",
                f"*Image strip in index.html: {inp}{title_spp}: the reference, each method's image and its error "
                f"heat map*")
        shown += 1
        if ref is None:
            rep.para(f"{inp}: the reference image is missing, so there is no error heat map.")
    if not shown:
        rep.para("No image strip could be drawn.")


# ---------------------------------------------------------------- main


def build(study_dir, out=None):
    name, declared, df, params = load(study_dir)
    rep = Report()
    rep.heading(1, f"Study {name}", "study")
    rep.para(f"Folder {os.path.abspath(study_dir)}; report of `ropsim study report` "
             "(analysis/study_report.py, docs/studies.md \"The report\").")
    section_points(rep, name, declared, df, params)
    section_quality(rep, df, params)
    section_equal_quality(rep, df, params)
    section_against_blend(rep, df, params)
    section_silicon(rep, df, params)
    section_axes(rep, df, params)
    section_fidelity(rep, df, params)
    section_bottlenecks(rep, df, params)
    section_images(rep, study_dir, df, params)
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>Study {html.escape(name)}</title><style>{CSS}</style><script>{SCRIPT}</script></head>\n"
            f"<body data-images=\"{rep.images}\">\n" + "\n".join(rep.html) + "\n</body></html>\n")
    out = out or os.path.join(study_dir, "report")
    os.makedirs(out, exist_ok=True)
    write_atomically(os.path.join(out, "index.html"), page)
    write_atomically(os.path.join(out, "summary.md"), "\n".join(rep.md) + "\n")
    return out, rep.images


def main(argv):
    args, out = argv[1:], None
    if len(args) == 3 and args[1] == "--out":
        args, out = args[:1], args[2]
    if len(args) != 1 or args[0] in ("-h", "--help"):
        print(__doc__.strip(), file=sys.stderr)
        return 0 if len(args) == 1 else 2
    study_dir = args[0]
    try:
        out, n = build(study_dir, out)
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
