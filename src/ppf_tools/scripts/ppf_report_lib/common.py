"""What ppf_report's parts share: the modes, stages and table columns, the error that stops a
report, the log line and the --stats CSV reader."""
import csv
import sys

MODES = ("knn", "ppf")
STAGES = ("preprocess", "deskew", "downsample", "ppf", "residuals", "update", "map_insert", "total")
PLOT_KINDS = ("trajectory", "stage_times", "map_size", "error_distance", "skeleton_scan")
# Columns of the main table; the ratio table divides the PPF row by the kNN row for these.
MAIN_COLUMNS = ("scans", "scans/s", "RTF", "total median ms", "total p95 ms", "map final",
                "map max", "peak RSS MB", "APE SE(3) m", "APE pos+yaw m", "RPE m/m")
RATIO_COLUMNS = ("scans/s", "total median ms", "map final", "peak RSS MB", "APE SE(3) m",
                 "APE pos+yaw m", "RPE m/m")


class ReportError(Exception):
    pass


def log(msg):
    print(f"ppf_report: {msg}", file=sys.stderr, flush=True)


def read_stats(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))
