"""Reports: the paper's evaluation re-run, measured, drawn and written.

- :mod:`.demo` / :mod:`.demo_report` -- Tables 3-4 and Figs. 8, 17-19 (``precontour demo``);
- :mod:`.compare` / :mod:`.compare_report` -- Figs. 11-16 and the paper's claims
  (``precontour compare``);
- :mod:`.progress` -- progress display of long runs.

The ``*_report`` modules draw and write (they alone import matplotlib); the others compute.
Import the module you need: this package imports none of them, so that computing never loads
matplotlib.
"""
