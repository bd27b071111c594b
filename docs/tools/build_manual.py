#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Build the manual (HTML) from docs/ with Sphinx and MyST, warnings as
errors, and check the result: every internal link of every page leads to an
existing page (and, with a #fragment, to an element of that id), every image
is there.

usage: build_manual.py [--out DIR] [--self-check]
  --out DIR     the HTML tree (default build/manual)
  --self-check  also build a two-page manual with a broken link, a missing
                image and a page left out of every table of contents, and
                require that each is reported (the checks can fail)

Exit status 0 when the manual builds clean and every link and image
resolves; 1 otherwise, with each problem printed."""
import html.parser
import os
import shutil
import subprocess
import sys
import tempfile
import urllib.parse

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))


def sphinx(src, out):
    """(returncode, warnings text) of a nitpicky, warnings-as-errors build."""
    cmd = ["/usr/bin/python3", "-m", "sphinx", "-W", "--keep-going", "-n", "-q", "-b", "html",
           "-d", os.path.join(out, ".doctrees"), src, out]
    r = subprocess.run(cmd, capture_output=True, text=True)
    return r.returncode, (r.stderr + r.stdout).strip()


class Page(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links, self.images = set(), [], []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if tag == "a" and a.get("href"):
            self.links.append(a["href"])
        if tag == "img" and a.get("src"):
            self.images.append(a["src"])


def check_html(out):
    """Problems of the internal links and images of an HTML tree."""
    pages = {}
    for d, _, names in os.walk(out):
        if os.path.basename(d).startswith(("_static", ".doctrees")):
            continue
        for n in names:
            if n.endswith(".html"):
                p = Page()
                with open(os.path.join(d, n), errors="replace") as f:
                    p.feed(f.read())
                pages[os.path.normpath(os.path.join(d, n))] = p
    bad = []
    for path, p in sorted(pages.items()):
        rel = os.path.relpath(path, out)
        for href in p.links:
            u = urllib.parse.urlparse(href)
            if u.scheme or href.startswith("//") or href.startswith("mailto:"):
                continue
            target = path if not u.path else os.path.normpath(os.path.join(os.path.dirname(path),
                                                                           urllib.parse.unquote(u.path)))
            if os.path.isdir(target):
                target = os.path.join(target, "index.html")
            if not os.path.exists(target):
                bad.append(f"{rel}: link {href}: no such file")
                continue
            if u.fragment and target.endswith(".html"):
                tp = pages.get(target)
                if tp is not None and urllib.parse.unquote(u.fragment) not in tp.ids:
                    bad.append(f"{rel}: link {href}: no element #{u.fragment}")
        for src in p.images:
            u = urllib.parse.urlparse(src)
            if u.scheme:
                continue
            target = os.path.normpath(os.path.join(os.path.dirname(path), urllib.parse.unquote(u.path)))
            if not os.path.isfile(target):
                bad.append(f"{rel}: image {src}: no such file")
    return bad, len(pages)


def build(src, out):
    if os.path.isdir(out):
        shutil.rmtree(out)
    rc, warnings = sphinx(src, out)
    problems = [w for w in warnings.splitlines() if "WARNING" in w or "ERROR" in w]
    if rc != 0 and not problems:
        problems = [warnings or f"sphinx-build exited {rc}"]
    bad, n = check_html(out) if os.path.isdir(out) else ([], 0)
    return problems + bad, n


SELF_PAGES = {
    "conf.py": "extensions = ['myst_parser']\nsource_suffix = {'.md': 'markdown'}\nmyst_heading_anchors = 3\n",
    "index.md": "# Home\n\n[to a missing page](nowhere.md)\n\n![missing](img/none.png)\n\n"
                "[a fine link](#home)\n\n```{toctree}\n```\n",
    "orphan.md": "# Orphan\n\nIn no table of contents.\n",
}


def self_check():
    with tempfile.TemporaryDirectory(prefix="gearsim-manual-self-") as tmp:
        src = os.path.join(tmp, "docs")
        os.makedirs(src)
        for n, t in SELF_PAGES.items():
            with open(os.path.join(src, n), "w") as f:
                f.write(t)
        problems, _ = build(src, os.path.join(tmp, "out"))
        text = "\n".join(problems)
        want = {"a missing page": "nowhere", "a missing image": "none.png", "a page in no toctree": "orphan"}
        missed = [k for k, v in want.items() if v not in text]
        return missed, text


def main():
    args = sys.argv[1:]
    out = os.path.join(ROOT, "build", "manual")
    if "--out" in args:
        out = os.path.abspath(args[args.index("--out") + 1])
    failed = False
    if "--self-check" in args:
        missed, text = self_check()
        if missed:
            print("self-check: not reported: " + ", ".join(missed) + "\n" + text)
            failed = True
        else:
            print("ok - self-check: a missing page, a missing image and a page in no toctree are reported")
    problems, n = build(os.path.join(ROOT, "docs"), out)
    for p in problems:
        print("FAIL - " + p)
    if not problems:
        print(f"ok - the manual builds with warnings as errors (nitpicky); {n} pages, "
              f"every internal link and image resolves: {os.path.join(out, 'index.html')}")
    return 1 if problems or failed else 0


if __name__ == "__main__":
    sys.exit(main())
