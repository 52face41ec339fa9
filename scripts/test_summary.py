#!/usr/bin/env python3
"""Summarizes the CTest results colcon left in build/<package>/Testing.

    test_summary.py [BUILD_DIR] [LABEL=BUILD_DIR ...] [--stages FILE]

Prints one line per test (status, package, name, seconds), the output tail of each failure, and
ends with the plain line 'N passed, M failed' (', K skipped' when some were skipped). Exit code:
0 only if at least one test ran and none failed.

Further build directories (the sanitizer builds of scripts/sanitize.sh) are given as
LABEL=DIR; their packages are shown as LABEL/<package>. --stages FILE adds CI stages that are
not CTest runs (a sanitizer build, a fuzzer run), one per line: 'PASS|FAIL|SKIP <seconds> <group>
<name>'. Everything is counted in the one final line.
"""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def latest_test_xml(pkg_build_dir):
    tag_file = os.path.join(pkg_build_dir, "Testing", "TAG")
    if os.path.isfile(tag_file):
        with open(tag_file) as f:
            tag = f.readline().strip()
        path = os.path.join(pkg_build_dir, "Testing", tag, "Test.xml")
        if os.path.isfile(path):
            return path
    candidates = glob.glob(os.path.join(pkg_build_dir, "Testing", "*", "Test.xml"))
    return max(candidates, key=os.path.getmtime) if candidates else None


def measurement(test, name):
    for m in test.iter("NamedMeasurement"):
        if m.get("name") == name:
            value = m.find("Value")
            return value.text if value is not None and value.text else ""
    return ""


def parse_args(argv):
    build_dirs, stages = [], []
    it = iter(argv)
    for arg in it:
        if arg == "--stages":
            stages.append(next(it))
        elif "=" in arg:
            label, _, path = arg.partition("=")
            build_dirs.append((label + "/", path))
        else:
            build_dirs.append(("", arg))
    return build_dirs or [("", "build")], stages


def read_stages(path):
    """(label, seconds, group, name) per well-formed line; a missing file is a failed stage."""
    if not os.path.isfile(path):
        return [("FAIL", "", "ci", f"stage results {path} missing")]
    rows = []
    with open(path) as f:
        for line in f:
            parts = line.split(None, 3)
            if len(parts) == 4 and parts[0] in ("PASS", "FAIL", "SKIP"):
                rows.append((parts[0], parts[1], parts[2], parts[3].strip()))
    return rows


def main():
    build_dirs, stage_files = parse_args(sys.argv[1:])
    passed, failed, skipped = 0, 0, 0
    failures = []
    packages = []
    for label, build_dir in build_dirs:
        packages += [(label, d) for d in sorted(glob.glob(os.path.join(build_dir, "*")))
                     if os.path.isdir(d)]
    for label, pkg_dir in packages:
        pkg = label + os.path.basename(pkg_dir)
        xml_path = latest_test_xml(pkg_dir)
        if xml_path is None:
            continue
        root = ET.parse(xml_path).getroot()
        for test in root.iter("Test"):
            if test.get("Status") is None:  # the TestList entries, not results
                continue
            status = test.get("Status", "")
            name = test.findtext("Name", default="?")
            output = test.findtext("Results/Measurement/Value", default="") or ""
            seconds = measurement(test, "Execution Time")
            completion = measurement(test, "Completion Status")
            # gtest_discover_tests marks GTEST_SKIP as "not run" with a skip completion status;
            # a test that is "not run" for any other reason (missing executable) is a failure.
            skip = (status == "notrun" and ("SKIP" in completion.upper() or "[  SKIPPED ]" in output)) or (
                status == "passed" and "[  SKIPPED ]" in output and "[  PASSED  ] 0 tests" in output)
            if skip:
                skipped += 1
                label = "SKIP"
            elif status == "passed":
                passed += 1
                label = "PASS"
            else:
                failed += 1
                label = "FAIL"
                failures.append((pkg, name, output))
            try:
                secs = f"{float(seconds):7.2f} s"
            except ValueError:
                secs = "      - s"
            print(f"{label}  {secs}  {pkg:<18} {name}")
    for path in stage_files:
        for label, seconds, group, name in read_stages(path):
            if label == "PASS":
                passed += 1
            elif label == "SKIP":
                skipped += 1
            else:
                failed += 1
                failures.append((group, name, "(see the stage's log above)"))
            try:
                secs = f"{float(seconds):7.2f} s"
            except ValueError:
                secs = "      - s"
            print(f"{label}  {secs}  {group:<18} {name}")
    for pkg, name, output in failures:
        print(f"\n----- FAILED {pkg} {name} (last lines) -----")
        print("\n".join(output.strip().splitlines()[-40:]))
    total = passed + failed + skipped
    print()
    if total == 0:
        print("no test results found under", ", ".join(d for _, d in build_dirs))
    line = f"{passed} passed, {failed} failed"
    if skipped:
        line += f", {skipped} skipped"
    print(line)
    return 0 if (total > 0 and failed == 0) else 1


if __name__ == "__main__":
    sys.exit(main())
