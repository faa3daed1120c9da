"""The study report's page (analysis/study_report.py): Report, which
collects the HTML body and the Markdown summary side by side (headings,
paragraphs, tables, figures as data URIs), the page's inline CSS and
script, and the atomic writer of index.html and summary.md.
"""
import base64
import html
import json
import os
import stat
import tempfile

from study_report_figures import render
from study_report_load import fmt_value

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

