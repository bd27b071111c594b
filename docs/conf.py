# SPDX-License-Identifier: MIT
# Sphinx configuration of the gearsim manual (MyST Markdown, Debian's
# python3-sphinx, python3-myst-parser and furo). Build it with
# `ninja -C build manual`, or by hand:
#   sphinx-build -W --keep-going -n -b html docs build/manual
import os

project = "gearsim"
author = "the gearsim authors"
copyright = "the gearsim authors, MIT licence"
release = version = "0.1.0"

extensions = ["myst_parser"]
source_suffix = {".md": "markdown"}
root_doc = "index"
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath", "deflist"]
exclude_patterns = ["man", "_build", "**/_build", "data/**/*.csv"]

html_theme = "furo" if os.environ.get("GEARSIM_MANUAL_THEME", "furo") == "furo" else "alabaster"
html_title = "gearsim manual"
html_static_path = []
html_show_sourcelink = False
# Pages are Markdown that also read well on a forge: a link to a file of the
# repository outside docs/ is offered as a download of that file.
