"""The study report's figures (analysis/study_report.py): the page's figure
size and fonts, plain and thinned tick labels, the grid of panels with a
legend column, and render(), which draws a figure to PNG and measures its
layout for the report's data-layout attribute.
"""
import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.text as mtext  # noqa: E402
from matplotlib import ticker  # noqa: E402
import numpy as np  # noqa: E402

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
