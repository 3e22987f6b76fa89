"""Every reference to a section of a doc in the repo's code and docs -- `docs/NAME.md,
"Section"` or `docs/NAME.md ("Section")` -- names a heading or a bold label that the
doc has (a prefix of it; "..." leaves out the rest). A section moved or renamed
without its references fails here, naming the file and line."""
import pathlib
import re
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
REF = re.compile(r"docs/([\w-]+\.md)(?:'s)?[\s#:,(]*[\"“]([^\"”]{3,300})[\"”]")
SUFFIXES = {".py", ".md", ".js", ".yaml", ".toml", ".sh", ".html"}


def norm(text: str) -> str:
    text = re.sub(r"\s*#:?\s", " ", text)            # a reference broken over comment lines
    return re.sub(r"\s+", " ", text).replace("`", "").strip()


def labels(doc: pathlib.Path) -> list[str]:
    text = doc.read_text()
    heads = [norm(line.lstrip("#")) for line in text.splitlines() if line.startswith("#")]
    bold = [norm(b).rstrip(".:") for b in re.findall(r"\*\*([^*]{3,120}?)\*\*", text)]
    return heads + bold


def references():
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the tracked files are unknown")
    for name in out.splitlines():
        path = ROOT / name
        if path.suffix not in SUFFIXES or not path.is_file():
            continue
        text = path.read_text(errors="replace")
        for m in REF.finditer(text):
            yield name, text.count("\n", 0, m.start()) + 1, m.group(1), norm(m.group(2))


def test_every_section_reference_names_a_section_of_its_doc():
    known = {doc.name: labels(doc) for doc in (ROOT / "docs").glob("*.md")}
    refs = list(references())
    checked, bad = 0, []
    for name, line, doc, section in refs:
        if doc not in known:
            continue
        want = section.split("...")[0].rstrip(" ,(") if "..." in section else section
        checked += 1
        if not any(label.startswith(want) for label in known[doc]):
            bad.append(f"{name}:{line}: docs/{doc} has no section \"{section}\"")
    assert checked >= 30, f"only {checked} references found: is the pattern still right?"
    assert not bad, "\n".join(bad)


def test_the_pattern_reads_a_reference_broken_over_comment_lines():
    text = "#: own pixels (docs/" + 'height.md, "Measured: large\n#: cutouts at 512 px")'   # split: not a reference here
    m = REF.search(text)
    assert m and m.group(1) == "height.md" and norm(m.group(2)) == "Measured: large cutouts at 512 px"
