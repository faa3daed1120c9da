"""The study report's section "Image strips" (analysis/study_report.py): per
input, the reference and each method's image with its error heat map, and
the colour bar of the maps.
"""
import html
import io
import json
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib import cm, colors, ticker  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from study_report_figures import DPI, render  # noqa: E402
from study_report_load import fmt_value, num, params_text, varying  # noqa: E402


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

