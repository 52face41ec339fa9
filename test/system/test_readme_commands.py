"""Every command in the README's bash blocks must run as written: the program exists (installed,
on PATH as colcon sets it up, or a script in the repository) and accepts every option the README
gives it. Cheap: each program is asked for its --help once; scripts are not run, their option
parsing (a `case` over the arguments) is read instead, since most of them would set up and build."""
import os
import re
import shlex
import shutil
import subprocess
import unittest

ROOT = os.environ.get("PPF_REPO_ROOT", os.path.join(os.path.dirname(__file__), "..", ".."))
# PPF_README: another file to check (to show that this test fails on a broken copy).
README = os.environ.get("PPF_README", os.path.join(ROOT, "README.md"))

# Programs of other projects the README shows next to ours: not checked, but named here, so that
# a command whose program is neither ours nor one of these fails instead of passing unchecked.
EXTERNAL = {"source", "export", "cd", "docker", "ros2", "rviz2", "colcon", "sudo"}
OPTION = re.compile(r"--[A-Za-z0-9][A-Za-z0-9-]*")


def readme_commands(text):
    """(line number, argv) of every command in the ```bash blocks: continuation lines joined,
    comments and leading VAR=value assignments dropped, `&&` / `;` / `|` chains split."""
    commands = []
    in_block = False
    pending, pending_line = "", 0
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped.startswith("```"):
            in_block = stripped == "```bash" if not in_block else False
            continue
        if not in_block:
            continue
        if not pending:
            pending_line = number
        if stripped.endswith("\\"):
            pending += stripped[:-1] + " "
            continue
        full, pending = pending + stripped, ""
        words = shlex.split(full, comments=True)
        current = []
        for word in words + [";"]:
            if word in ("&&", "||", ";", "|"):
                while current and re.match(r"^[A-Za-z_][A-Za-z0-9_]*=", current[0]):
                    current.pop(0)
                if current:
                    commands.append((pending_line, current))
                current = []
            else:
                current.append(word)
    return commands


def inline_spans(text):
    """(line number, program, options) of every `ppf_x ... --option ...` or `scripts/x --option`
    code span outside the code blocks (spans without an option name a tool, or a package)."""
    spans = []
    in_block = False
    for number, line in enumerate(text.splitlines(), 1):
        if line.strip().startswith("```"):
            in_block = not in_block
            continue
        if in_block:
            continue
        for span in re.findall(r"`([^`]+)`", line):
            words = span.split()
            options = OPTION.findall(span)
            if options and re.fullmatch(r"ppf_[a-z0-9_]+|scripts/[\w./-]+", words[0]):
                spans.append((number, words[0], options))
    return spans


def find_program(name):
    """The installed program: PATH first (colcon test runs with the install sourced), then the
    workspace's install tree."""
    found = shutil.which(name)
    if found:
        return found
    install = os.path.join(ROOT, "install")
    if os.path.isdir(install):
        for package in sorted(os.listdir(install)):
            candidate = os.path.join(install, package, "bin", name)
            if os.access(candidate, os.X_OK):
                return candidate
    return None


def script_options(path):
    """Options a bash script accepts: the patterns of its argument `case` branches."""
    with open(path) as f:
        text = f.read()
    options = set()
    for pattern in re.findall(r"^\s*([-A-Za-z0-9|]+)\)", text, re.M):
        options.update(p for p in pattern.split("|") if p.startswith("--"))
    return options


class ReadmeCommandsTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        with open(README) as f:
            cls.text = f.read()
        cls.commands = readme_commands(cls.text)
        cls.help_cache = {}

    def help_text(self, program):
        if program not in self.help_cache:
            out = subprocess.run([program, "--help"], capture_output=True, text=True, timeout=60,
                                 stdin=subprocess.DEVNULL)
            self.help_cache[program] = out.stdout + out.stderr
        return self.help_cache[program]

    def test_readme_has_the_two_commands(self):
        programs = [argv[0] for _, argv in self.commands]
        self.assertIn("scripts/demo.sh", programs)
        self.assertIn("scripts/test.sh", programs)
        self.assertIn("ppf_offline", programs)
        self.assertIn("ppf_node", programs)

    def test_every_command_runs_as_written(self):
        problems = []
        checked = 0
        for line, argv in self.commands:
            program = argv[0]
            options = [w.split("=")[0] for w in argv[1:] if OPTION.fullmatch(w.split("=")[0])]
            where = f"README line {line}: {' '.join(argv)}"
            if program in EXTERNAL:
                continue
            checked += 1
            self.check(program, options, where, problems)
        self.assertGreater(checked, 10, "too few README commands found: did the blocks change?")
        if problems:
            self.fail("\n".join(problems))

    def test_every_option_in_the_text_exists(self):
        # The tool table and the prose name options in `ppf_x --option ...` spans too.
        problems = []
        for line, program, options in inline_spans(self.text):
            self.check(program, options, f"README line {line}: `{program} ...`", problems)
        if problems:
            self.fail("\n".join(problems))

    def check(self, program, options, where, problems):
        """Appends to `problems` why `program options...` would not run as written."""
        if program.startswith("scripts/"):
            path = os.path.join(ROOT, program)
            if not os.access(path, os.X_OK):
                problems.append(f"{where}: {program} is not an executable script")
                return
            accepted = script_options(path)
            problems.extend(f"{where}: {program} has no option {option}"
                            for option in options if option not in accepted)
            return
        if not program.startswith("ppf_"):
            problems.append(f"{where}: {program} is neither one of ours nor a known external "
                            "program (add it to EXTERNAL if it is)")
            return
        path = find_program(program)
        if path is None:
            problems.append(f"{where}: {program} is not installed (not on PATH, not in "
                            f"{os.path.join(ROOT, 'install')})")
            return
        if not options:
            return
        text = self.help_text(path)
        if "usage" not in text.lower():
            problems.append(f"{where}: {program} --help prints no usage text")
            return
        problems.extend(f"{where}: {program} --help does not list {option}" for option in options
                        if not re.search(r"(?<![\w-])" + re.escape(option) + r"(?![\w-])", text))


class ExtractionTest(unittest.TestCase):
    def test_joins_continuations_and_drops_comments_and_assignments(self):
        text = ("text\n```bash\nA=1 ppf_x --a 1 \\\n  --b 2   # comment --c\n"
                "ppf_y --d && scripts/z.sh --e\n```\n```yaml\nkey: --f\n```\n")
        self.assertEqual(readme_commands(text),
                         [(3, ["ppf_x", "--a", "1", "--b", "2"]), (5, ["ppf_y", "--d"]),
                          (5, ["scripts/z.sh", "--e"])])

    def test_script_options_reads_case_patterns(self):
        self.assertIn("--quick", script_options(os.path.join(ROOT, "scripts/test.sh")))
        self.assertIn("--minutes", script_options(os.path.join(ROOT, "scripts/soak.sh")))
        self.assertNotIn("--bogus", script_options(os.path.join(ROOT, "scripts/test.sh")))


if __name__ == "__main__":
    unittest.main()
