"""Every reference to a section of a doc in the repo's code and docs -- `docs/<NAME>.md,
"Section"`, `docs/<NAME>.md ("Section")`, `docs/<NAME>.md, 'Section'` (error messages) or,
inside docs/, a link `[text](<NAME>.md), "Section"` -- names a doc that exists and a
heading or a bold label that the doc has (a prefix of it; "..." leaves out the rest).
A reference broken over comment lines (``#``, ``#:``, ``//``) is read whole. A markdown
link to a section (`[text](NAME.md#anchor)`, `[text](#anchor)`) in README.md and docs/
leads to a heading. A section or doc moved or renamed without its references fails
here, naming the file and line."""
import pathlib
import re
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
# the doc (docs/NAME.md, or a markdown link's (NAME.md) inside docs/), then the section in double
# quotes, or in single quotes when it starts with a capital (a single quote is also an apostrophe)
REF = re.compile(r"(?:docs/(?P<doc>[\w-]+\.md)|\]\((?P<link>[\w-]+\.md)\))(?:'s)?[\s#/:,(]*"
                 r"(?:[\"“](?P<dq>[^\"”]{3,300})[\"”]|'(?P<sq>[A-Z][^'\n]{2,300})')")
# a further section of the same doc: `, "B"`, ` and "B"`, `; "B"` after the first (a short
# parenthesis such as "(the seventh)" may follow each)
MORE = re.compile(r"(?:\s*\([^()\"”]{1,40}\))?(?:\s*(?:,|;|and|or)\s*)+(?:\s|#:?|//)*[\"“](?P<dq>[^\"”]{3,300})[\"”]")
SUFFIXES = {".py", ".md", ".js", ".yaml", ".toml", ".sh", ".html"}


def norm(text: str) -> str:
    text = re.sub(r"\s*(?:#:?|//)\s", " ", text)     # a reference broken over comment lines
    return re.sub(r"\s+", " ", text).replace("`", "").strip()


def doc_of(m: re.Match) -> str:
    return m.group("doc") or m.group("link")


def section_of(m: re.Match) -> str:
    return norm(m.group("dq") or m.group("sq"))


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
            yield name, text.count("\n", 0, m.start()) + 1, doc_of(m), section_of(m)
            for more in sections_after(text, m):
                yield name, text.count("\n", 0, more.start()) + 1, doc_of(m), norm(more.group("dq"))


def sections_after(text: str, m: re.Match):
    """The further sections a reference lists after its first (``MORE``)."""
    end = m.end()
    while (more := MORE.match(text, end)) is not None:
        yield more
        end = more.end()


def test_every_section_reference_names_a_section_of_its_doc():
    known = {doc.name: labels(doc) for doc in (ROOT / "docs").glob("*.md")}
    refs = list(references())
    checked, bad = 0, []
    for name, line, doc, section in refs:
        if doc not in known:
            bad.append(f"{name}:{line}: no doc docs/{doc} (its section \"{section}\")")
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
    assert m and doc_of(m) == "height.md" and section_of(m) == "Measured: large cutouts at 512 px"


@pytest.mark.parametrize("text, doc, section", [
    ("// horizon (docs/own-" + 'photo.md,\n// "The horizon"). The', "own-photo.md", "The horizon"),
    ("(see docs/own-" + "photo.md, 'The horizon')", "own-photo.md", "The horizon"),
    ("docs/server" + ".md's \"Previews of soft shadows\"", "server.md", "Previews of soft shadows"),
    ("[the record](height-" + 'record.md), "Measured:\nmore kinds"', "height-record.md", "Measured: more kinds"),
])
def test_the_pattern_reads_each_reference_style(text, doc, section):   # the texts split: not references here
    m = REF.search(text)
    assert m and doc_of(m) == doc and section_of(m) == section


@pytest.mark.parametrize("text", [
    "docs/" + "server.md's page and the user's own",              # an apostrophe, not a quote
    '"colour (docs/' + 'height.md)"), ("auto", "Auto")',             # a string's end, not a quote
    '- [docs/auto' + '.md](docs/auto.md): "model no more than a scene needs"',   # a link's tagline
])
def test_what_is_not_a_reference(text):
    assert REF.search(text) is None


def test_the_pattern_reads_every_section_of_a_list():
    text = ('(docs/height-' + 'record.md, "Rules fixed before measuring: thin parts of large\n'
            'cutouts" and "Measured: thin parts"; "Train the eighth" (the record), "Measured: a" and the rest')
    m = REF.search(text)
    assert [section_of(m)] + [norm(x.group("dq")) for x in sections_after(text, m)] == [
        "Rules fixed before measuring: thin parts of large cutouts", "Measured: thin parts", "Train the eighth",
        "Measured: a"]


def anchor(heading: str) -> str:
    """GitHub's anchor of a markdown heading: lower case, punctuation but hyphens dropped,
    spaces made hyphens (``## 6. Another background`` -> ``6-another-background``)."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(doc: pathlib.Path) -> set[str]:
    """The anchors of a doc's headings (outside code blocks; a repeated one gets -1, -2...)."""
    seen, fenced = {}, False
    for line in doc.read_text().splitlines():
        fenced ^= line.startswith("```")
        m = None if fenced else re.match(r"#+\s+(.*)", line)
        if m:
            a = anchor(m.group(1))
            seen[a] = seen.get(a, -1) + 1
            if seen[a]:
                seen[f"{a}-{seen[a]}"] = 0
    return set(seen)


LINK = re.compile(r"\]\(([\w/.-]*\.md)?#([\w-]+)\)")


def test_every_markdown_link_to_a_section_names_a_heading_it_has():
    """`[text](NAME.md#anchor)` and `[text](#anchor)` in README.md and docs/ lead to a heading."""
    docs = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    checked, bad = 0, []
    for doc in docs:
        text = doc.read_text()
        for m in LINK.finditer(text):
            target = (doc.parent / m.group(1)) if m.group(1) else doc
            checked += 1
            if not target.is_file() or m.group(2) not in anchors(target):
                bad.append(f"{doc.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}: no #{m.group(2)} "
                           f"in {m.group(1) or doc.name}")
    assert checked >= 30, f"only {checked} links found: is the pattern still right?"
    assert not bad, "\n".join(bad)


def test_anchors_as_github_makes_them():
    assert anchor("6. Another background: templates and their handles") == \
        "6-another-background-templates-and-their-handles"
    assert anchor("Where the cutout's pixel height comes from") == "where-the-cutouts-pixel-height-comes-from"
    assert anchor("pixgraph.SoftShadowSSN") == "pixgraphsoftshadowssn"
