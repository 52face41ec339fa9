"""ppf_report's plots: trajectories (SE(3)-aligned to the reference as for APE), stage times, map
size, error over distance and the skeleton scan (the paper's Fig. 1). numpy and matplotlib are
imported inside the functions: --check runs without them."""
import csv
import os

from ppf_report_lib.common import MODES, STAGES, ReportError, read_stats


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            v = [float(x) for x in line.split()]
            if len(v) >= 8:
                rows.append(v[:8])
    return rows


def associate(ref, est, max_diff=0.01):
    """Pairs each estimate with the nearest reference stamp (as ppf_eval, max 10 ms apart)."""
    import bisect
    ref_t = [r[0] for r in ref]
    pairs = []
    for e in est:
        k = bisect.bisect_left(ref_t, e[0])
        best = None
        for j in (k - 1, k):
            if 0 <= j < len(ref_t) and (best is None or abs(ref_t[j] - e[0]) < abs(ref_t[best] - e[0])):
                best = j
        if best is not None and abs(ref_t[best] - e[0]) <= max_diff:
            pairs.append((ref[best], e))
    return pairs


def umeyama_se3(src, dst):
    """R, t minimising |dst - (R src + t)| (positions, N x 3 numpy arrays)."""
    import numpy as np
    mu_s, mu_d = src.mean(0), dst.mean(0)
    cov = (dst - mu_d).T @ (src - mu_s) / len(src)
    U, _, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1
    R = U @ S @ Vt
    return R, mu_d - R @ mu_s


def aligned_errors(ref_path, est_path):
    """SE(3)-aligned estimate positions, reference positions, per-pose error and distance."""
    import numpy as np
    pairs = associate(read_tum(ref_path), read_tum(est_path))
    if len(pairs) < 3:
        raise ReportError(f"{est_path}: fewer than 3 poses match {ref_path}")
    ref = np.array([p[0][1:4] for p in pairs])
    est = np.array([p[1][1:4] for p in pairs])
    R, t = umeyama_se3(est, ref)
    est_aligned = est @ R.T + t
    err = np.linalg.norm(est_aligned - ref, axis=1)
    dist = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ref, axis=0), axis=1))])
    return ref, est_aligned, err, dist


MODE_STYLE = {"knn": dict(color="tab:orange", label="kNN"), "ppf": dict(color="tab:blue", label="PPF")}


def plot_sequence(rec, plot_dir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    name = rec["name"]
    files = {}

    def save(fig, kind):
        path = os.path.join(plot_dir, f"{name}_{kind}.png")
        fig.savefig(path, dpi=90)
        plt.close(fig)
        files[kind] = os.path.basename(path)

    stats = {m: read_stats(rec["modes"][m]["stats"]) for m in MODES}

    # Top view: both modes against the reference (SE(3)-aligned as for APE), or as estimated.
    fig, ax = plt.subplots(figsize=(7, 6))
    errors = {}
    for m in MODES:
        if rec["ref"]:
            ref, est, err, dist = aligned_errors(rec["ref"], rec["modes"][m]["traj"])
            errors[m] = (dist, err)
            if m == MODES[0]:
                ax.plot(ref[:, 0], ref[:, 1], color="black", lw=2.5, alpha=0.35, label="ground truth")
            ax.plot(est[:, 0], est[:, 1], lw=1.2, **MODE_STYLE[m])
        else:
            est = np.array([p[1:4] for p in read_tum(rec["modes"][m]["traj"])])
            ax.plot(est[:, 0], est[:, 1], lw=1.2, **MODE_STYLE[m])
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"{name}: top view" + (" (SE(3)-aligned to the reference)" if rec["ref"] else
                                        " (no reference: as estimated)"))
    ax.grid(alpha=0.3)
    ax.legend()
    save(fig, "trajectory")

    # Per-scan stage times, one panel per mode, same scale.
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True, sharey=True)
    for ax, m in zip(axes, MODES):
        rows = [r for r in stats[m] if r["pose_valid"] == "1"]
        t = np.array([float(r["stamp"]) for r in rows])
        layers = [np.array([float(r[f"t_{st}_ms"]) for r in rows]) for st in STAGES[:-1]]
        ax.stackplot(t - t[0], *layers, labels=[s.replace("_", " ") for s in STAGES[:-1]])
        ax.set_ylabel("ms per scan")
        ax.set_title(f"{MODE_STYLE[m]['label']}: median total "
                     f"{rec['modes'][m]['total_median']:.2f} ms")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=7, ncol=4)
    axes[-1].set_xlabel("time since first scan with a pose [s]")
    fig.suptitle(f"{name}: stage times per scan")
    save(fig, "stage_times")

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for m in MODES:
        rows = [r for r in stats[m] if r["pose_valid"] == "1"]
        t = np.array([float(r["stamp"]) for r in rows])
        ax.plot(t - t[0], [int(r["map_size"]) / 1000.0 for r in rows], **MODE_STYLE[m])
    ax.set_xlabel("time since first scan with a pose [s]")
    ax.set_ylabel("kNN map size [thousand points]")
    ax.set_title(f"{name}: local map size")
    ax.grid(alpha=0.3)
    ax.legend()
    save(fig, "map_size")

    fig, ax = plt.subplots(figsize=(8, 4.5))
    if errors:
        for m in MODES:
            dist, err = errors[m]
            ax.plot(dist, err, **MODE_STYLE[m])
        ax.set_xlabel("distance travelled (reference) [m]")
        ax.set_ylabel("position error, SE(3)-aligned [m]")
    else:
        ax.text(0.5, 0.5, "no reference trajectory", ha="center", va="center")
    ax.set_title(f"{name}: error over distance")
    ax.grid(alpha=0.3)
    ax.legend() if errors else None
    save(fig, "error_distance")

    plot_skeleton_scan(rec, plt, np, save)
    return files, errors


def plot_skeleton_scan(rec, plt, np, save):
    """The paper's Fig. 1: one scan's points by PPF label, its skeleton planes as rectangles."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    d = rec["dump_dir"]
    with open(os.path.join(d, "scan_info.csv"), newline="") as f:
        info = next(csv.DictReader(f))
    pts = read_stats(os.path.join(d, "scan_points.csv"))
    planes = read_stats(os.path.join(d, "scan_planes.csv"))
    center = np.array([float(info["x"]), float(info["y"]), float(info["z"])])
    xyz = np.array([[float(p["x"]), float(p["y"]), float(p["z"])] for p in pts])
    labels = np.array([p["label"] for p in pts])
    # The sensor's surroundings (most of the scan, at most 30 m): far points make the planes too
    # small to see, a room needs less.
    horizontal = np.linalg.norm(xyz[:, :2] - center[:2], axis=1)
    radius = float(np.clip(np.ceil(np.percentile(horizontal, 90) * 1.1), 8.0, 30.0))
    near = horizontal < radius
    fig = plt.figure(figsize=(10, 5.2))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    colors = {"skeleton": "tab:blue", "scattered": "tab:red", "discarded": "tab:gray"}
    for lab in ("scattered", "discarded", "skeleton"):
        sel = near & (labels == lab)
        if not sel.any():
            continue
        txt = f"{lab} ({int((labels == lab).sum())})"
        ax3.scatter(xyz[sel, 0], xyz[sel, 1], xyz[sel, 2], s=0.3, c=colors[lab], label=txt)
        ax2.scatter(xyz[sel, 0], xyz[sel, 1], s=0.8, c=colors[lab], label=txt, zorder=3)
    cmap = plt.get_cmap("tab20")
    polys = []
    fitted = 0
    for i, p in enumerate(planes):
        if p["fitted"] != "1":
            continue  # window planes not seen in this scan
        fitted += 1
        c = np.array([float(p["cx"]), float(p["cy"]), float(p["cz"])])
        u = np.array([float(p["ux"]), float(p["uy"]), float(p["uz"])]) * float(p["u_half"])
        v = np.array([float(p["vx"]), float(p["vy"]), float(p["vz"])]) * float(p["v_half"])
        corners = np.array([c + u + v, c + u - v, c - u - v, c - u + v])
        polys.append(corners)
        col = cmap(i % 20)
        # Outlines only: seen from above, filled walls and ground would hide the points.
        ax2.fill(corners[:, 0], corners[:, 1], fill=False, edgecolor=col, lw=1.0, zorder=2)
    if polys:
        pc = Poly3DCollection(polys, alpha=0.3)
        pc.set_facecolor([cmap(i % 20) for i in range(len(polys))])
        pc.set_edgecolor("k")
        ax3.add_collection3d(pc)
    ax3.set_xlim(center[0] - radius, center[0] + radius)
    ax3.set_ylim(center[1] - radius, center[1] + radius)
    ax3.set_zlim(center[2] - radius / 3, center[2] + radius / 3)
    ax3.view_init(elev=35, azim=-60)
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax2.set_aspect("equal")
    ax2.set_xlim(center[0] - radius, center[0] + radius)
    ax2.set_ylim(center[1] - radius, center[1] + radius)
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.legend(loc="upper right", fontsize=7, markerscale=5)
    ax2.set_title("top view: points, plane outlines")
    fig.suptitle(f"{rec['name']}: PPF scan {info['index']}, {fitted} skeleton planes fitted in it "
                 f"(rectangles), points within {radius:g} m by label")
    save(fig, "skeleton_scan")
    rec["dump_points"] = len(pts)
    rec["dump_planes_fitted"] = fitted
