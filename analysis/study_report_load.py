"""The study report's input (analysis/study_report.py): a study folder's
results table read from results.db, the swept parameters, the metric
columns the sections read, and the helpers that read and format values.
"""
import json
import os
import sqlite3
import urllib.parse

try:
    import tomllib
except ImportError:  # Python < 3.11: the parameters come from params.json alone
    tomllib = None

import numpy as np
import pandas as pd

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


def sorted_values(series):
    """The distinct values of a parameter: numerically sorted when they are
    all numbers, else in the order of the points."""
    vals = list(pd.unique(series.dropna()))
    nums = pd.to_numeric(pd.Series(vals, dtype=object), errors="coerce")
    if len(vals) and nums.notna().all():
        return [v for _, v in sorted(zip(nums, vals), key=lambda p: p[0])]
    return vals
