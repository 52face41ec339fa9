"""The modules of the ppf_report command (scripts/ppf_report.py.in): common (names and the error
they share), runs (the tools run and their figures), plots, check (the report checker)."""
