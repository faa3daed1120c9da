"""The ropsim runs behind the tables of docs/results.md (scripts/results.py):
Context runs `ropsim run` for a report and `ropsim study run` for a study
(each study once, however many tables read it) in a work folder, and ROOT,
the source tree.
"""
import concurrent.futures
import json
import os
import re
import sqlite3
import subprocess
import threading

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class Context:
    def __init__(self, ropsim, jobs, work):
        self.ropsim = ropsim
        self.jobs = jobs
        self.work = work
        self.count = 0
        self.studies = {}
        self.lock = threading.Lock()
        self.study_locks = {}

    def tmp(self, name):
        with self.lock:
            self.count += 1
            return os.path.join(self.work, "%03d-%s" % (self.count, name))

    def call(self, args, cwd=None):
        p = subprocess.run([self.ropsim, *args], cwd=cwd or self.work, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
        if p.returncode != 0:
            raise RuntimeError("ropsim %s failed (exit %d):\n%s" % (" ".join(args), p.returncode, p.stderr))
        return p.stdout

    def report(self, args):
        """`ropsim run ARGS --report R --quiet`: the report as a dict."""
        base = self.tmp("run")
        self.call(["run", *args, "--quiet", "--out", base + ".png", "--report", base + ".json"])
        with open(base + ".json") as f:
            return json.load(f)

    def reports(self, arg_lists):
        """Several runs, self.jobs at a time; reports in the order of arg_lists."""
        with concurrent.futures.ThreadPoolExecutor(self.jobs) as ex:
            return list(ex.map(self.report, arg_lists))

    def study(self, study_file, extra_toml=None):
        """`ropsim study run STUDY --out DIR -j N`: an sqlite3 connection to its results.

        extra_toml: replaces the study's [axes] lines given as {key: toml value}
        (a copy of the study in the work folder, its paths relative to studies/ made absolute)."""
        cache_key = (study_file, tuple(sorted((extra_toml or {}).items(), key=lambda kv: kv[0])))
        with self.lock:
            key_lock = self.study_locks.setdefault(cache_key, threading.Lock())
        with key_lock:  # tables run side by side; one run of each study
            if cache_key not in self.studies:
                self.studies[cache_key] = self._run_study(study_file, extra_toml)
        out = self.studies[cache_key]
        return out, sqlite3.connect(os.path.join(out, "results.db"))  # a connection per caller (thread)

    def _run_study(self, study_file, extra_toml):
        out = self.tmp("study")
        path = os.path.join(ROOT, study_file)
        if extra_toml:
            text = open(path).read()
            for key, value in extra_toml.items():
                if value is None:  # drop the key
                    text = re.sub(r"(?m)^%s = .*\n" % re.escape(key), "", text)
                    continue
                text = re.sub(r"(?m)^%s = .*$" % re.escape(key), lambda m: "%s = %s" % (key, value), text)
                if not re.search(r"(?m)^%s = " % re.escape(key), text):
                    text = text.rstrip("\n") + "\n%s = %s\n" % (key, value)
            # the copy lives in the work folder: its paths relative to studies/ made absolute
            text = text.replace('"../', '"%s/' % ROOT)
            path = self.tmp(os.path.basename(path))
            with open(path, "w") as f:
                f.write(text)
        self.call(["study", "run", path, "--out", out, "-j", str(self.jobs)])
        return out
