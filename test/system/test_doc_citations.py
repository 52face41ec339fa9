"""Every section of docs/ that a comment in src/ cites must exist: a comment citing
`docs/<file>.md, "<Section>"` (or `docs/<file>.md "<Section>"`, the quotes may follow on the next
comment line; a list `docs/<file>.md, "<A>", "<B>" and "<C>"` cites each) names a file in the repository's docs/ and a heading of that file, exactly as
written after its #'s. A renamed or removed section otherwise leaves the code pointing at
nothing. Cheap: reads the sources, builds nothing."""
import os
import re
import tempfile
import unittest

# PPF_REPO_ROOT: the repository to check (another copy shows that this test fails on a broken
# citation).
ROOT = os.environ.get("PPF_REPO_ROOT", os.path.join(os.path.dirname(__file__), "..", ".."))

C_LIKE = (".cpp", ".hpp", ".h", ".cc", ".c", ".ipp")
HASH_COMMENTED = (".py", ".cmake", ".sh")
# A file, then one section in quotes or a list of them ("A", "B" and "C"): each is a citation.
CITATION = re.compile(r'(docs/[\w./-]+\.md),?\s*("[^"]+"(?:\s*(?:,|and|or|,\s*and)\s*"[^"]+")*)')
SECTION = re.compile(r'"([^"]+)"')
HEADING = re.compile(r"^#+\s+(.*?)\s*#*\s*$")


def comment_marker(path):
    name = os.path.basename(path)
    if name.endswith(C_LIKE):
        return "//"
    if name.endswith(HASH_COMMENTED) or name == "CMakeLists.txt":
        return "#"
    return None


def comment_blocks(text, marker):
    """(first line number, text) of every run of consecutive comment lines, the marker and the
    code before it dropped and the lines joined by a space, so that a citation broken over two
    comment lines reads as one."""
    blocks = []
    current, start = [], 0
    for number, line in enumerate(text.splitlines(), 1):
        at = line.find(marker)
        if at < 0:
            if current:
                blocks.append((start, " ".join(current)))
                current = []
            continue
        if not current:
            start = number
        current.append(line[at + len(marker):].strip())
    if current:
        blocks.append((start, " ".join(current)))
    return blocks


def citations(root):
    """(path relative to root, line, docs file, section) of every citation in src/."""
    found = []
    for directory, _, files in os.walk(os.path.join(root, "src")):
        for name in sorted(files):
            path = os.path.join(directory, name)
            marker = comment_marker(path)
            if marker is None:
                continue
            with open(path, encoding="utf-8", errors="replace") as f:
                text = f.read()
            for line, block in comment_blocks(text, marker):
                for match in CITATION.finditer(block):
                    for section in SECTION.findall(match.group(2)):
                        found.append((os.path.relpath(path, root), line, match.group(1),
                                      section))
    return found


def headings(path):
    result = set()
    in_code = False
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.lstrip().startswith("```"):
                in_code = not in_code
                continue
            match = None if in_code else HEADING.match(line)
            if match:
                result.add(match.group(1))
    return result


class DocCitationsTest(unittest.TestCase):
    def test_cited_sections_exist(self):
        found = citations(ROOT)
        # The sources cite a dozen sections; none found means this test stopped reading them.
        self.assertGreaterEqual(len(found), 10, "citations found in src/: %d" % len(found))
        missing = []
        cache = {}
        for source, line, doc, section in found:
            doc_path = os.path.join(ROOT, doc)
            if doc not in cache:
                cache[doc] = headings(doc_path) if os.path.isfile(doc_path) else None
            if cache[doc] is None:
                missing.append('%s:%d: %s does not exist' % (source, line, doc))
            elif section not in cache[doc]:
                missing.append('%s:%d: %s has no section "%s"' % (source, line, doc, section))
        self.assertEqual(missing, [], "\n" + "\n".join(missing))

    def test_a_list_cites_each_of_its_sections(self):
        with tempfile.TemporaryDirectory() as root:
            os.makedirs(os.path.join(root, "src"))
            os.makedirs(os.path.join(root, "docs"))
            with open(os.path.join(root, "src", "a.hpp"), "w", encoding="utf-8") as f:
                f.write('// Behaviour: docs/b.md, "One", "Two" and\n// "Three". Not "Four".\nint a;\n')
            self.assertEqual(
                [(doc, section) for _, _, doc, section in citations(root)],
                [("docs/b.md", "One"), ("docs/b.md", "Two"), ("docs/b.md", "Three")])


if __name__ == "__main__":
    unittest.main()
