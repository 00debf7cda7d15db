"""``dsim serve``: a model database and web front end over dsim's Python API.

Upload FMUs and .ssp scenes (checked as untrusted input), browse them, assemble
scenes, launch runs in their own processes and watch them live, compare runs
with a baseline and look at sweeps.  An optional extra (``pip install
'dsim[serve]'``); the command-line tool does not need it.  See docs/serve.md.
"""
