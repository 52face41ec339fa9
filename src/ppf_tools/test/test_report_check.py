#!/usr/bin/python3
# The report checker (ppf_report --check) must accept the short report as written and refuse a
# copy of it with one defect each: a ratio that no longer matches its rows, a word where a number
# belongs, a missing load average, a plot missing from report.md, a truncated PNG, a PNG whose
# IHDR was altered, a plot too small to show anything.
#
#   test_report_check.py <configured ppf_report script> <report dir made by ppf_report --short>
import importlib.machinery
import importlib.util
import os
import re
import shutil
import sys
import tempfile
import unittest

SCRIPT, REPORT = sys.argv[1], sys.argv[2]


def load_report_module():
    loader = importlib.machinery.SourceFileLoader("ppf_report", SCRIPT)
    spec = importlib.util.spec_from_loader("ppf_report", loader)
    mod = importlib.util.module_from_spec(spec)
    loader.exec_module(mod)
    return mod


R = load_report_module()


class ReportChecker(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="ppf_report_check_")
        self.dir = os.path.join(self.tmp, "r")
        shutil.copytree(REPORT, self.dir, ignore=shutil.ignore_patterns("runs", "sequences"))
        self.md = os.path.join(self.dir, "report.md")
        with open(self.md) as f:
            self.text = f.read()

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def write(self, text):
        self.assertNotEqual(text, self.text, "the defect was not applied")
        with open(self.md, "w") as f:
            f.write(text)

    def refused(self, pattern):
        with self.assertRaises(R.ReportError) as cm:
            R.check_report(self.dir)
        self.assertRegex(str(cm.exception), pattern)

    def plot(self):
        return os.path.join(self.dir, "plots", sorted(os.listdir(os.path.join(self.dir, "plots")))[0])

    def test_the_report_as_written_passes(self):
        self.assertRegex(R.check_report(self.dir), r"^1 sequences x 2 modes, 5 plots$")

    def test_a_ratio_that_does_not_match_its_rows(self):
        lines = self.text.splitlines()
        i = next(k for k, l in enumerate(lines) if l.startswith("| sequence | scans/s |")) + 2
        cells = lines[i].split("|")
        cells[2] = f" {float(cells[2]) * 1.1 + 0.01:.3f} "  # the scans/s ratio, 10 % off
        lines[i] = "|".join(cells)
        self.write("\n".join(lines) + "\n")
        self.refused(r"ratio .* scans/s: .* but the rows give")

    def test_a_word_where_a_number_belongs(self):
        self.write(re.sub(r"(\| knn \| )[0-9]+ ", r"\1many ", self.text, count=1))
        self.refused(r"'many' is not a number")

    def test_a_missing_load_average(self):
        self.write(re.sub(r"- load average at end: .*\n", "", self.text))
        self.refused(r"load average at end missing")

    def test_a_plot_missing_from_the_report(self):
        self.write(re.sub(r"!\[[^\]]*\]\(plots/[^)]*_map_size\.png\)\n", "", self.text))
        self.refused(r"plot map_size of .* not in report\.md")

    def test_a_truncated_png(self):
        with open(self.plot(), "r+b") as f:
            f.truncate(20)
        self.refused(r"not a 13-byte IHDR|not a PNG")

    def test_a_png_with_an_altered_header(self):
        with open(self.plot(), "r+b") as f:
            f.seek(18)  # inside the width
            b = f.read(1)
            f.seek(18)
            f.write(bytes([b[0] ^ 0x01]))
        self.refused(r"IHDR CRC mismatch")

    def test_a_png_too_small_to_show_anything(self):
        # A valid 1 x 1 PNG in place of a plot.
        import zlib
        def chunk(kind, data):
            return (len(data).to_bytes(4, "big") + kind + data +
                    zlib.crc32(kind + data).to_bytes(4, "big"))
        png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", bytes([0, 0, 0, 1, 0, 0, 0, 1, 8, 0, 0, 0, 0])) +
               chunk(b"IDAT", zlib.compress(b"\x00\x00")) + chunk(b"IEND", b""))
        with open(self.plot(), "wb") as f:
            f.write(png)
        self.refused(r"1 x 1 pixels")


class ScanDump(unittest.TestCase):
    """ppf_offline --dump-scan, as the report ran it: the dumped scan is the one its stats row
    describes, its labels are the core's, its pose is the trajectory's, and the planes fitted in
    it lie on its points."""

    @classmethod
    def setUpClass(cls):
        runs = os.path.join(REPORT, "runs")
        seq = sorted(os.listdir(runs))[0]
        cls.dump = os.path.join(runs, seq, "scan_dump")
        cls.info = R.read_stats(os.path.join(cls.dump, "scan_info.csv"))[0]
        cls.points = R.read_stats(os.path.join(cls.dump, "scan_points.csv"))
        cls.planes = R.read_stats(os.path.join(cls.dump, "scan_planes.csv"))
        cls.stats = R.read_stats(os.path.join(runs, seq, "ppf_stats.csv"))

    def test_the_dump_is_the_scan_its_stats_row_describes(self):
        row = self.stats[int(self.info["index"])]
        self.assertEqual(row["stamp"], self.info["stamp"])
        self.assertEqual(row["status"], self.info["status"])
        self.assertEqual(self.info["mode"], "ppf")
        self.assertEqual(int(self.info["points"]), len(self.points))
        self.assertEqual(int(row["downsampled_points"]), len(self.points))
        counts = {k: sum(1 for p in self.points if p["label"] == k)
                  for k in ("skeleton", "scattered", "discarded")}
        self.assertEqual(sum(counts.values()), len(self.points), "unknown label")
        self.assertEqual(counts["skeleton"], int(row["skeleton_points"]))
        self.assertEqual(counts["scattered"], int(row["scattered_points"]))
        self.assertEqual(counts["discarded"], int(row["discarded_points"]))
        self.assertGreater(counts["skeleton"], 0)

    def test_the_dump_pose_is_the_trajectory_pose_times_the_extrinsic(self):
        # T_world_lidar = T_world_imu (ppf.tum at the scan's stamp) * T_imu_lidar (the sequence's
        # calibration.yaml, which the report layered after the preset).
        import numpy as np
        import yaml
        seq_dir = os.path.dirname(self.dump)
        with open(os.path.join(seq_dir, "ppf.log")) as f:
            cmd = f.readline().split()
        configs = [cmd[i + 1] for i, a in enumerate(cmd) if a == "--config"]
        with open(configs[-1]) as f:
            t_il = np.array(yaml.safe_load(f)["extrinsic"]["T_imu_lidar"]["translation"], float)
        stamp = float(self.info["stamp"])
        pose = min(R.read_tum(os.path.join(seq_dir, "ppf.tum")), key=lambda r: abs(r[0] - stamp))
        self.assertLess(abs(pose[0] - stamp), 1e-5)
        x, y, z, w = pose[4:8]
        rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        expected = np.array(pose[1:4]) + rot @ t_il
        got = np.array([float(self.info[k]) for k in ("x", "y", "z")])
        np.testing.assert_allclose(got, expected, atol=1e-5)

    def test_the_planes_fitted_in_the_scan_lie_on_its_points(self):
        import numpy as np
        fitted = [p for p in self.planes if p["fitted"] == "1"]
        self.assertGreater(len(fitted), 0)
        n = np.array([[float(p[k]) for k in ("nx", "ny", "nz")] for p in fitted])
        d = np.array([float(p["d"]) for p in fitted])
        np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
        # The in-plane axes (of the latest fit's inlier scatter) lie in the plane: within about a
        # degree of orthogonal to its normal (the plane's estimate is refined after that fit).
        for p in fitted:
            normal = np.array([float(p[k]) for k in ("nx", "ny", "nz")])
            for ax in ("u", "v"):
                axis = np.array([float(p[ax + k]) for k in "xyz"])
                self.assertLess(abs(axis @ normal), 0.02)
                self.assertGreater(float(p[ax + "_half"]), 0.0)
        # Each plane fitted in the scan took its strict inliers, points within ppf.delta (0.2 m,
        # reference.yaml), from this scan's downsampled points: about that many dumped points lie
        # within delta of it (2 % slack: the fit used the predicted pose, the dump the estimated
        # one). Points or planes in another frame (LiDAR instead of world, map instead of
        # gravity-aligned) would leave few of them there.
        xyz = np.array([[float(p["x"]), float(p["y"]), float(p["z"])] for p in self.points])
        for p, normal, offset in zip(fitted, n, d):
            near = int((np.abs(xyz @ normal + offset) < 0.2).sum())
            self.assertGreaterEqual(near, 0.98 * int(p["inliers"]), f"plane {p['track_id']}")
        # And the skeleton points are the ones near those planes: most of them within delta of one.
        sk = np.array([[float(p["x"]), float(p["y"]), float(p["z"])]
                       for p in self.points if p["label"] == "skeleton"])
        dist = np.abs(sk @ n.T + d).min(axis=1)
        self.assertGreater(float((dist < 0.2).mean()), 0.5, f"median {np.median(dist):.3f} m")


class PlotData(unittest.TestCase):
    def test_error_over_distance_is_the_error_ppf_eval_scores(self):
        # The trajectory and error plots align the estimate themselves (Umeyama SE(3)); their
        # errors' RMSE must be ppf_eval's SE(3) APE of the same files.
        import numpy as np
        runs = os.path.join(REPORT, "runs")
        for seq in sorted(os.listdir(runs)):
            for mode in R.MODES:
                with open(os.path.join(runs, seq, f"{mode}_ape_se3.txt")) as f:
                    text = f.read()
                cmd = text.splitlines()[0].split()
                ref, est = cmd[cmd.index("--ref") + 1], cmd[cmd.index("--est") + 1]
                _, _, err, dist = R.aligned_errors(ref, est)
                self.assertAlmostEqual(float(np.sqrt((err ** 2).mean())), R.parse_eval_rmse(text),
                                       delta=1e-5, msg=f"{seq} {mode}")
                self.assertTrue(np.all(np.diff(dist) >= 0))


if __name__ == "__main__":
    unittest.main(argv=[sys.argv[0], "-v"])
