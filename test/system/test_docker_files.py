"""CI machines have no container engine (scripts/container_check.sh builds and runs the image with
podman outside CI), so the Docker files are checked against the set-up script CI runs: same base
distribution, same script, nothing fetched around it, a runtime stage that carries no build tree,
and a compose file with the settings Fast DDS needs in containers."""
import glob
import json
import os
import re
import shlex
import unittest

import yaml

ROOT = os.environ.get("PPF_REPO_ROOT", os.path.join(os.path.dirname(__file__), "..", ".."))


def read(rel):
    with open(os.path.join(ROOT, rel)) as f:
        return f.read()


def dockerfile_instructions(text):
    """(INSTRUCTION, argument) pairs with line continuations joined and comments dropped."""
    joined = re.sub(r"\\\n", " ", text)
    out = []
    for line in joined.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        word, _, rest = line.partition(" ")
        out.append((word.upper(), rest.strip()))
    return out


class DockerfileTest(unittest.TestCase):
    def setUp(self):
        self.ins = dockerfile_instructions(read("docker/Dockerfile"))

    def test_parses_into_known_instructions(self):
        known = {"FROM", "ENV", "WORKDIR", "COPY", "RUN", "ENTRYPOINT", "CMD", "ARG", "LABEL", "EXPOSE"}
        self.assertTrue(self.ins)
        for word, arg in self.ins:
            self.assertIn(word, known, f"unknown instruction {word}")
            self.assertTrue(arg, f"{word} without argument")
        self.assertEqual(self.ins[0][0], "FROM")

    def stages(self):
        """[(base, name, [(INSTRUCTION, argument), ...]), ...] in file order."""
        out = []
        for word, arg in self.ins:
            if word == "FROM":
                parts = arg.split()
                name = parts[2] if len(parts) == 3 and parts[1].upper() == "AS" else None
                out.append((parts[0], name, []))
            else:
                out[-1][2].append((word, arg))
        return out

    def test_every_stage_is_debian_12_like_the_setup_script_expects(self):
        for base, _, _ in self.stages():
            self.assertIn(base, ("debian:12", "debian:bookworm", "debian:12-slim", "debian:bookworm-slim"))

    def test_steps_are_the_setup_script(self):
        runs = [arg for word, arg in self.ins if word == "RUN"]
        self.assertTrue(any("scripts/setup.sh --deps-only" in r for r in runs), runs)
        self.assertTrue(any("scripts/setup.sh --no-deps" in r for r in runs), runs)
        for r in runs:
            # Everything is installed by the script from Debian packages: no side channels.
            for forbidden in ("apt-get install", "curl ", "wget ", "pip install", "git clone"):
                self.assertNotIn(forbidden, r, f"Dockerfile step bypasses scripts/setup.sh: {r}")

    def test_setup_script_flags_exist(self):
        script = read("scripts/setup.sh")
        for flag in ("--deps-only", "--no-deps", "--runtime-packages", "--runtime-deps"):
            self.assertIn(flag, script)

    def test_runtime_package_list_of_the_built_tree(self):
        # The image's build stage runs exactly this on its install tree. It once failed there:
        # ldd over every executable, ppf_report (a Python script) among them, made xargs exit
        # 123 and pipefail the whole step.
        if not os.path.isdir(os.path.join(ROOT, "install", "ppf_dds_node")):
            self.skipTest("no built install/ tree at the repository root (build first)")
        import subprocess
        out = subprocess.run(["bash", "scripts/setup.sh", "--runtime-packages"], cwd=ROOT,
                             capture_output=True, text=True, timeout=300)
        self.assertEqual(out.returncode, 0, out.stderr)
        pkgs = out.stdout.split()
        self.assertTrue(all(re.fullmatch(r"[a-z0-9][a-z0-9.+-]+", p) for p in pkgs), pkgs)
        self.assertTrue(any(p.startswith("libfastrtps") for p in pkgs), pkgs)
        self.assertTrue(any(p.startswith("libyaml-cpp") for p in pkgs), pkgs)

    def test_final_stage_holds_the_install_tree_and_runtime_packages_only(self):
        stages = self.stages()
        self.assertGreaterEqual(len(stages), 2, "one stage: compilers and build trees ship")
        build_name = stages[0][1]
        self.assertTrue(build_name, "the build stage needs a name for COPY --from")
        final = stages[-1][2]
        runs = [arg for word, arg in final if word == "RUN"]
        self.assertTrue(runs and all("scripts/setup.sh --runtime-deps" in r for r in runs), runs)
        copies = [arg for word, arg in final if word == "COPY"]
        from_build = [c for c in copies if c.startswith(f"--from={build_name}")]
        self.assertTrue(any(c.split()[1].endswith("/install") for c in from_build), copies)
        for c in copies:
            src = c.split()[-2]
            self.assertNotIn(src, (".", "src", "build"), f"final stage copies sources: {c}")
        # The build stage skips the tests and lists what the runtime needs.
        build_runs = " ".join(arg for word, arg in stages[0][2] if word == "RUN")
        self.assertIn("PPF_BUILD_TESTING=OFF", build_runs)
        self.assertIn("scripts/setup.sh --runtime-packages", build_runs)

    def test_build_context_leaves_host_build_trees_out(self):
        ignored = {line.strip() for line in read(".dockerignore").splitlines()}
        for tree in ("build", "install", "log", "test/js/node_modules"):
            self.assertIn(tree, ignored)

    def test_default_command_starts_the_node_with_a_shipped_config(self):
        cmd = dict(self.ins)["CMD"]
        self.assertIn("ppf_node", cmd)
        config = re.search(r'/opt/lio-ppf/(config/[^"\s]+)', cmd).group(1)
        self.assertTrue(os.path.isfile(os.path.join(ROOT, config)), f"{config} missing")
        entry = dict(self.ins)["ENTRYPOINT"]
        self.assertIn("docker/entrypoint.sh", entry)
        self.assertTrue(os.access(os.path.join(ROOT, "docker/entrypoint.sh"), os.X_OK))

    def test_dds_profile_named_in_the_image_exists(self):
        env = " ".join(arg for word, arg in self.ins if word == "ENV")
        m = re.search(r"FASTRTPS_DEFAULT_PROFILES_FILE=/opt/lio-ppf/(\S+)", env)
        self.assertIsNotNone(m)
        self.assertTrue(os.path.isfile(os.path.join(ROOT, m.group(1))), f"{m.group(1)} missing")


class ComposeTest(unittest.TestCase):
    def setUp(self):
        self.doc = yaml.safe_load(read("docker/compose.yaml"))

    def test_node_and_replay_services(self):
        services = self.doc["services"]
        self.assertIn("node", services)
        self.assertIn("replay", services)
        self.assertIn("ppf_node", " ".join(services["node"]["command"]))
        self.assertIn("ppf_replay", " ".join(services["replay"]["command"]))
        self.assertEqual(services["node"]["build"]["dockerfile"], "docker/Dockerfile")

    def test_fast_dds_can_share_memory_and_discover(self):
        for name, svc in self.doc["services"].items():
            # Shared memory needs a common /dev/shm (ipc: host or a large shm_size); discovery
            # between containers needs a common network.
            self.assertTrue(svc.get("ipc") == "host" or "shm_size" in svc, f"{name}: no shared /dev/shm")
            self.assertEqual(svc.get("network_mode"), "host", f"{name}: not on the host network")
            profile = svc["environment"]["FASTRTPS_DEFAULT_PROFILES_FILE"]
            rel = profile.replace("/opt/lio-ppf/", "")
            self.assertTrue(os.path.isfile(os.path.join(ROOT, rel)), f"{name}: {rel} missing")

    def test_commands_use_installed_tools_with_documented_flags(self):
        replay = " ".join(self.doc["services"]["replay"]["command"])
        words = shlex.split(replay.replace(";", " ; "))
        self.assertIn("--scene", words)
        self.assertIn("--bag", words)

    def test_valid_under_the_compose_specification(self):
        # `docker compose` v2 (compose-go) and podman read the Compose Specification; v2 itself is
        # not packaged for Debian 12, but Debian's docker-compose (scripts/setup.sh installs it)
        # ships the specification's JSON schema, which rejects unknown keys and wrong types.
        schemas = glob.glob("/usr/lib/python3/dist-packages/compose/config/compose_spec.json")
        if not schemas:
            self.skipTest("Compose Specification schema absent: apt-get install docker-compose")
        import jsonschema

        with open(schemas[0]) as f:
            schema = json.load(f)
        validator = jsonschema.Draft7Validator(schema)
        errors = [f"{'/'.join(map(str, e.path))}: {e.message}" for e in validator.iter_errors(self.doc)]
        self.assertEqual(errors, [])
        # The check has teeth: a misspelt key is refused, as v2 refuses it.
        bad = json.loads(json.dumps(self.doc))
        bad["services"]["node"]["stop_signall"] = "SIGINT"
        self.assertTrue(any("stop_signall" in e.message for e in validator.iter_errors(bad)))


if __name__ == "__main__":
    unittest.main()
