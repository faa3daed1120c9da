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
# The report is built by the modules beside this file, one concern each:
#   study_report_load.py      the study folder's results, parameters and values
#   study_report_figures.py   figure layout and rendering (render())
#   study_report_page.py      the HTML and Markdown writer (Report), the atomic write
#   study_report_quality.py   points, quality against cost, equal quality
#   study_report_blend.py     against blend
#   study_report_metrics.py   quality against silicon, parameters against metrics, bottlenecks
#   study_report_fidelity.py  the fidelities against the cycle model
#   study_report_images.py    image strips with error heat maps
import html
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from study_report_blend import HEADLINE, against_blend_frame, ratio, section_against_blend  # noqa: E402
from study_report_fidelity import section_fidelity  # noqa: E402
from study_report_figures import panel_grid, put_legend, render, spans_decade  # noqa: E402
from study_report_images import section_images  # noqa: E402
from study_report_load import StudyError, fmt_value, load, num  # noqa: E402
from study_report_metrics import section_axes, section_bottlenecks, section_silicon  # noqa: E402
from study_report_page import CSS, SCRIPT, Report, write_atomically  # noqa: E402
from study_report_quality import (pareto, section_equal_quality, section_points, section_quality,  # noqa: E402
                                  spp_at_rmse)

# build() and main(), and the names analysis/real_frames.py and analysis/study_cost.py use.
__all__ = ["HEADLINE", "StudyError", "against_blend_frame", "build", "fmt_value", "load", "main", "num",
           "panel_grid", "pareto", "put_legend", "ratio", "render", "spans_decade", "spp_at_rmse",
           "write_atomically"]


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
