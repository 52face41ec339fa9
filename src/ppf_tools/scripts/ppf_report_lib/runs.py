"""ppf_report's runs: ppf_sim sequences generated once, ppf_offline in both modes on a sequence
(wall time and the child's own peak RSS measured), ppf_eval's scores, and the per-mode figures of
the report's tables."""
import math
import os
import re
import shlex
import shutil
import subprocess
import time

from ppf_report_lib.common import MODES, STAGES, ReportError, log, read_stats


def run_measured(cmd, log_path):
    """Runs cmd, output to log_path; returns (exit code, wall s, peak RSS MB of that child)."""
    with open(log_path, "w") as out:
        out.write("$ " + shlex.join(cmd) + "\n")
        out.flush()
        t0 = time.monotonic()
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT)
        # wait4 gives this child's own rusage (ru_maxrss in kB on Linux), not the sum over
        # children that RUSAGE_CHILDREN would give.
        _, status, rusage = os.wait4(p.pid, 0)
        wall = time.monotonic() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
    return p.returncode, wall, rusage.ru_maxrss / 1024.0


def tail(path, n=5):
    try:
        with open(path) as f:
            return "".join(f.readlines()[-n:])
    except OSError:
        return ""


def find_tool(name, given):
    path = given or shutil.which(name)
    if not path or not os.access(path, os.X_OK):
        raise ReportError(f"{name} not found (put the workspace's install on PATH: "
                          f"source install/setup.bash, or pass --{name.replace('_', '-')})")
    return path


def complete_sequence(d):
    return os.path.exists(os.path.join(d, "metadata.yaml")) and os.path.exists(
        os.path.join(d, "groundtruth.tum"))


def ensure_sequence(tools, scene, lidar, duration, workdir):
    """Generates scene/lidar with ppf_sim once (same names and seed as ppf_compare's cache)."""
    name = f"{scene}_{lidar}_{int(duration)}s"
    d = os.path.join(workdir, name)
    if complete_sequence(d):
        return d
    staging = os.path.join(workdir, f".staging_{name}_{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    os.makedirs(staging)
    out = os.path.join(staging, name)  # ppf_sim names the bag files after the directory
    log(f"generating {name} with ppf_sim")
    cmd = [tools["ppf_sim"], "--scene", scene, "--lidar", lidar, "--duration", f"{duration:g}",
           "--seed", "1", "--storage", "mcap", "--out", out]
    sim_log = d + ".sim.log"
    rc, _, _ = run_measured(cmd, sim_log)
    if rc != 0 or not complete_sequence(out):
        raise ReportError(f"ppf_sim failed for {name} (exit {rc}):\n{tail(sim_log)}")
    if not complete_sequence(d):
        shutil.rmtree(d, ignore_errors=True)
        os.rename(out, d)
    shutil.rmtree(staging, ignore_errors=True)
    return d


def percentile(values, q):
    """Linear interpolation between closest ranks (numpy's default)."""
    if not values:
        return float("nan")
    v = sorted(values)
    pos = (len(v) - 1) * q
    lo = math.floor(pos)
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (v[hi] - v[lo]) * (pos - lo)


def parse_eval_rmse(text):
    m = re.search(r"^\s*rmse\t([0-9.eE+-]+)\s*$", text, re.M)
    if not m:
        raise ReportError("no rmse line in ppf_eval's output:\n" + text[-500:])
    return float(m.group(1))


def run_eval(tools, args, log_path):
    cmd = [tools["ppf_eval"]] + args
    r = subprocess.run(cmd, capture_output=True, text=True)
    with open(log_path, "w") as f:
        f.write("$ " + shlex.join(cmd) + "\n" + r.stdout + r.stderr)
    if r.returncode != 0:
        raise ReportError(f"ppf_eval failed (exit {r.returncode}): {r.stderr.strip()}")
    return parse_eval_rmse(r.stdout)


def summarize_run(stats_rows, wall_s, peak_rss_mb):
    """The per-mode figures of the main table from ppf_offline's --stats CSV."""
    valid = [r for r in stats_rows if r["pose_valid"] == "1"]
    if not valid:
        raise ReportError("no scan with a pose")
    s = {"scans": len(stats_rows), "scans_with_pose": len(valid)}
    for st in STAGES:
        vals = [float(r[f"t_{st}_ms"]) for r in valid]
        s[f"{st}_median"] = percentile(vals, 0.5)
        s[f"{st}_p95"] = percentile(vals, 0.95)
    core_ms = sum(float(r["t_total_ms"]) for r in stats_rows)
    # As ppf_offline's summary: scans per second of core time (every scan, initializing included).
    s["scans_per_s"] = 1000.0 * len(stats_rows) / core_ms if core_ms > 0 else float("nan")
    stamps = [float(r["stamp"]) for r in stats_rows]
    s["data_s"] = (max(stamps) - min(stamps)) + (max(stamps) - min(stamps)) / max(1, len(stamps) - 1)
    s["wall_s"] = wall_s
    # Real-time factor of the whole offline run (bag reading and decoding included): seconds of
    # data per second of wall time, > 1 is faster than the sensor.
    s["rtf"] = s["data_s"] / wall_s if wall_s > 0 else float("nan")
    maps = [int(r["map_size"]) for r in valid]
    s["map_final"] = maps[-1]
    s["map_max"] = max(maps)
    s["peak_rss_mb"] = peak_rss_mb
    return s


def run_sequence(tools, seq, opts, out_dir, runs_dir):
    """Both modes on one sequence; returns the sequence's record for the report."""
    name = seq["name"]
    rec = {"name": name, "bag": seq["bag"], "ref": seq.get("ref"), "configs": seq["configs"],
           "modes": {}}
    seq_dir = os.path.join(runs_dir, name)
    os.makedirs(seq_dir, exist_ok=True)
    dump_index = None
    for mode in MODES:
        traj = os.path.join(seq_dir, f"{mode}.tum")
        stats = os.path.join(seq_dir, f"{mode}_stats.csv")
        cmd = [tools["ppf_offline"], "--bag", seq["bag"]]
        for c in seq["configs"]:
            cmd += ["--config", c]
        cmd += ["--mode", mode, "--out", traj, "--stats", stats, "--threads", str(opts.threads),
                "--quiet"]
        if mode == "ppf":
            # Fig. 1: the middle scan of the run (known from the kNN run's scan count).
            dump_index = opts.dump_scan if opts.dump_scan >= 0 else rec["modes"]["knn"]["scans"] // 2
            cmd += ["--dump-scan", str(dump_index), "--dump-dir", os.path.join(seq_dir, "scan_dump")]
        log(f"{name}: {mode}")
        run_log = os.path.join(seq_dir, f"{mode}.log")
        rc, wall, rss = run_measured(cmd, run_log)
        if rc != 0:
            raise ReportError(f"ppf_offline failed on {name} ({mode}, exit {rc}):\n{tail(run_log)}")
        m = summarize_run(read_stats(stats), wall, rss)
        m["command"] = shlex.join(cmd)
        m["traj"] = traj
        m["stats"] = stats
        if seq.get("ref"):
            ref = seq["ref"]
            base = ["--ref", ref, "--est", traj]
            m["ape_se3"] = run_eval(tools, ["ape"] + base + ["--align", "se3"],
                                    os.path.join(seq_dir, f"{mode}_ape_se3.txt"))
            m["ape_posyaw"] = run_eval(tools, ["ape"] + base + ["--align", "posyaw"],
                                       os.path.join(seq_dir, f"{mode}_ape_posyaw.txt"))
            m["rpe"] = run_eval(tools, ["rpe"] + base + ["--delta", "1", "--delta-unit", "m"],
                                os.path.join(seq_dir, f"{mode}_rpe.txt"))
        rec["modes"][mode] = m
    rec["dump_dir"] = os.path.join(seq_dir, "scan_dump")
    rec["dump_index"] = dump_index
    return rec
