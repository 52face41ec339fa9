"""The set-up script is what every user and CI runs first: it must be valid bash, idempotent, fetch
nothing but Debian/npm packages, and CI must call exactly the README's test command."""
import os
import re
import subprocess
import unittest

ROOT = os.environ.get("PPF_REPO_ROOT", os.path.join(os.path.dirname(__file__), "..", ".."))


def read(rel):
    with open(os.path.join(ROOT, rel)) as f:
        return f.read()


class SetupScriptTest(unittest.TestCase):
    def test_valid_bash(self):
        for script in ("scripts/setup.sh", "scripts/test.sh", ".ci/run", "scripts/demo.sh"):
            path = os.path.join(ROOT, script)
            self.assertTrue(os.access(path, os.X_OK), f"{script} not executable")
            subprocess.run(["bash", "-n", path], check=True)

    def test_downloads_only_packages(self):
        for script in ("scripts/setup.sh", "scripts/test.sh", "scripts/demo.sh", "docker/Dockerfile"):
            text = read(script)
            for forbidden in ("curl ", "wget ", "git clone", "pip install", "http://", "https://"):
                self.assertNotIn(forbidden, text, f"{script} fetches outside Debian/npm: {forbidden}")

    def test_every_required_debian_package_is_listed(self):
        text = read("scripts/setup.sh")
        block = re.search(r"PPF_DEBIAN_PACKAGES=\((.*?)\)", text, re.S).group(1)
        listed = set(block.split())
        for pkg in ("libfastrtps-dev", "fastddsgen", "libfastcdr-dev", "libpcl-dev", "libeigen3-dev",
                    "colcon", "libgtest-dev", "libyaml-cpp-dev", "libsqlite3-dev", "liblz4-dev",
                    "libzstd-dev", "libbz2-dev", "cyclonedds-dev", "python3-rosbag",
                    "python3-sensor-msgs", "python3-matplotlib"):
            self.assertIn(pkg, listed)

    def test_second_run_installs_nothing(self):
        # Everything is installed by now (this test runs after the build): a second run must find
        # all packages present and not touch apt.
        out = subprocess.run([os.path.join(ROOT, "scripts/setup.sh"), "--deps-only"], cwd=ROOT,
                             capture_output=True, text=True, timeout=300)
        self.assertEqual(out.returncode, 0, out.stderr)
        self.assertIn("all", out.stdout)
        self.assertNotIn("installing", out.stdout.replace("installing npm", ""))

    def test_ci_runs_the_readme_test_command(self):
        ci = read(".ci/run")
        readme = read("README.md")
        self.assertIn("scripts/test.sh", ci)
        self.assertIn("scripts/test.sh", readme)
        self.assertIn("scripts/demo.sh", readme)


if __name__ == "__main__":
    unittest.main()
