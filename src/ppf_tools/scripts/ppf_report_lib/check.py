"""ppf_report --check: is a report directory complete and consistent? Every number parses, the
PPF/kNN ratios agree with the rows they divide, every plot is a PNG of a sensible size. Never looks
at what the times are."""
import math
import os
import re
import zlib

from ppf_report_lib.common import MAIN_COLUMNS, MODES, PLOT_KINDS, RATIO_COLUMNS, ReportError


def png_size(path):
    """(width, height) of a PNG whose signature and IHDR chunk (length, type, CRC) are valid."""
    with open(path, "rb") as f:
        head = f.read(33)
    if len(head) < 33 or head[:8] != b"\x89PNG\r\n\x1a\n":
        raise ReportError(f"{path}: not a PNG (signature)")
    length = int.from_bytes(head[8:12], "big")
    if length != 13 or head[12:16] != b"IHDR":
        raise ReportError(f"{path}: first chunk is not a 13-byte IHDR")
    if zlib.crc32(head[12:29]) != int.from_bytes(head[29:33], "big"):
        raise ReportError(f"{path}: IHDR CRC mismatch")
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def parse_table(lines, header_start):
    """Rows (lists of cells) of the markdown table whose header line starts with header_start."""
    for i, line in enumerate(lines):
        if line.startswith(header_start):
            header = [c.strip() for c in line.strip().strip("|").split("|")]
            rows = []
            for row in lines[i + 2:]:
                if not row.startswith("|"):
                    break
                rows.append([c.strip() for c in row.strip().strip("|").split("|")])
            for r in rows:
                if len(r) != len(header):
                    raise ReportError(f"table '{header_start}': row {r} has {len(r)} cells, "
                                      f"header {len(header)}")
            return header, rows
    raise ReportError(f"no table starting with '{header_start}'")


def decimals(s):
    return len(s.split(".")[1]) if "." in s else 0


def number(s, what):
    if not re.fullmatch(r"-?[0-9]+(\.[0-9]+)?", s):
        raise ReportError(f"{what}: '{s}' is not a number")
    v = float(s)
    if not math.isfinite(v):
        raise ReportError(f"{what}: '{s}' is not finite")
    return v


def check_report(report_dir):
    """Raises ReportError naming the first problem; returns a one-line summary."""
    path = os.path.join(report_dir, "report.md")
    if not os.path.isfile(path):
        raise ReportError(f"{path} missing")
    with open(path) as f:
        text = f.read()
    lines = text.splitlines()
    check_command_and_machine(text)
    values = check_summary(lines)
    sequences = sorted({s for s, _ in values})
    check_ratios(lines, values, sequences)
    check_stage_times(lines, values)
    images = check_plots(report_dir, text, sequences)
    return f"{len(sequences)} sequences x {len(MODES)} modes, {len(images)} plots"


def check_command_and_machine(text):
    """The exact command that made the report and the machine it ran on."""
    m = re.search(r"```\n(.+)\n```", text)
    if not m or "ppf_report" not in m.group(1):
        raise ReportError("the command that made the report is missing")
    if not re.search(r"^- CPU: \S", text, re.M):
        raise ReportError("CPU model missing")
    if not re.search(r"^- cores: [1-9][0-9]*$", text, re.M):
        raise ReportError("core count missing")
    for when in ("start", "end"):
        if not re.search(rf"^- load average at {when}: [0-9.]+ [0-9.]+ [0-9.]+$", text, re.M):
            raise ReportError(f"load average at {when} missing")
    if not re.search(r"^- core threads \(--threads\): [0-9]+$", text, re.M):
        raise ReportError("thread count missing")


def check_summary(lines):
    """The main table: every cell a number in its range, both modes for every sequence. Returns
    {(sequence, mode): {column: (value, printed cell) or None for n/a}}."""
    header, rows = parse_table(lines, "| sequence | mode | scans |")
    if header[2:] != list(MAIN_COLUMNS):
        raise ReportError(f"summary columns {header[2:]}")
    values = {}
    for r in rows:
        seq, mode = r[0], r[1]
        if mode not in MODES:
            raise ReportError(f"summary: unknown mode '{mode}'")
        if (seq, mode) in values:
            raise ReportError(f"summary: {seq}/{mode} twice")
        row = {}
        for c, cell in zip(MAIN_COLUMNS, r[2:]):
            if cell == "n/a" and c.startswith(("APE", "RPE")):
                row[c] = None
                continue
            row[c] = (number(cell, f"{seq}/{mode} {c}"), cell)
            if row[c][0] < 0:
                raise ReportError(f"{seq}/{mode} {c} negative: {cell}")
        for c in ("scans", "scans/s", "RTF", "total median ms", "map max", "peak RSS MB"):
            if row[c][0] <= 0:
                raise ReportError(f"{seq}/{mode} {c} is {row[c][1]}, must be > 0")
        if row["total median ms"][0] > row["total p95 ms"][0]:
            raise ReportError(f"{seq}/{mode}: median above p95")
        if row["map final"][0] > row["map max"][0]:
            raise ReportError(f"{seq}/{mode}: final map above its maximum")
        values[(seq, mode)] = row
    sequences = sorted({s for s, _ in values})
    if not sequences:
        raise ReportError("summary table is empty")
    for s in sequences:
        for mode in MODES:
            if (s, mode) not in values:
                raise ReportError(f"summary: {s} has no {mode} row")
        if values[(s, "knn")]["scans"][0] != values[(s, "ppf")]["scans"][0]:
            raise ReportError(f"{s}: the two modes saw different scan counts")
        refs = {values[(s, m)]["APE SE(3) m"] is None for m in MODES}
        if len(refs) != 1:
            raise ReportError(f"{s}: APE given for one mode only")
    return values


def check_ratios(lines, values, sequences):
    """The PPF / kNN table: each ratio within the rounding of the two cells it divides."""
    header, rows = parse_table(lines, "| sequence | scans/s |")
    if header[1:] != list(RATIO_COLUMNS):
        raise ReportError(f"ratio columns {header[1:]}")
    if sorted(r[0] for r in rows) != sequences:
        raise ReportError(f"ratio rows {sorted(r[0] for r in rows)} != sequences {sequences}")
    for r in rows:
        seq = r[0]
        for c, cell in zip(RATIO_COLUMNS, r[1:]):
            k, p = values[(seq, "knn")][c], values[(seq, "ppf")][c]
            if k is None or p is None:
                if cell != "n/a":
                    raise ReportError(f"ratio {seq} {c}: '{cell}' without both values")
                continue
            ratio = number(cell, f"ratio {seq} {c}")
            # Interval of p/k given the rounding of every printed number.
            ek, ep = 0.5 * 10 ** -decimals(k[1]), 0.5 * 10 ** -decimals(p[1])
            if k[0] - ek <= 0:
                raise ReportError(f"ratio {seq} {c}: kNN value {k[1]} too small for a ratio")
            lo = max(0.0, p[0] - ep) / (k[0] + ek)
            hi = (p[0] + ep) / (k[0] - ek)
            er = 0.5 * 10 ** -decimals(cell)
            if not (lo - er - 1e-12 <= ratio <= hi + er + 1e-12):
                raise ReportError(f"ratio {seq} {c}: {cell} but the rows give {p[1]} / {k[1]} = "
                                  f"{p[0] / k[0]:.4f}")


def check_stage_times(lines, values):
    """The stage table: median / p95 pairs, its total column equal to the summary's."""
    header, rows = parse_table(lines, "| sequence | mode | preprocess |")
    if sorted((r[0], r[1]) for r in rows) != sorted(values):
        raise ReportError("stage table rows differ from the summary's")
    for r in rows:
        for st, cell in zip(header[2:], r[2:]):
            parts = [x.strip() for x in cell.split("/")]
            if len(parts) != 2:
                raise ReportError(f"stage {r[0]}/{r[1]} {st}: '{cell}' is not median / p95")
            med, p95 = (number(x, f"stage {r[0]}/{r[1]} {st}") for x in parts)
            if med > p95:
                raise ReportError(f"stage {r[0]}/{r[1]} {st}: median {med} > p95 {p95}")
        total = [x.strip() for x in r[-1].split("/")]
        v = values[(r[0], r[1])]
        if total[0] != v["total median ms"][1] or total[1] != v["total p95 ms"][1]:
            raise ReportError(f"stage {r[0]}/{r[1]}: total {r[-1]} differs from the summary")


def check_plots(report_dir, text, sequences):
    """Every plot referenced, present, a PNG of a sensible size; each sequence has every kind.
    Returns the images report.md references."""
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    for s in sequences:
        for kind in PLOT_KINDS:
            if f"plots/{s}_{kind}.png" not in images:
                raise ReportError(f"plot {kind} of {s} not in report.md")
    for img in images:
        p = os.path.join(report_dir, img)
        if not os.path.isfile(p):
            raise ReportError(f"{img} referenced but missing")
        w, h = png_size(p)
        if not (300 <= w <= 4000 and 200 <= h <= 4000):
            raise ReportError(f"{img}: {w} x {h} pixels")
        size = os.path.getsize(p)
        if not (5_000 <= size <= 3_000_000):
            raise ReportError(f"{img}: {size} bytes")
    return images
