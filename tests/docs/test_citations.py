"""Citations a reader can open: every source the code and the docs cite is in the repository or
named so that it can be looked up (docs/reference/references.md).

* No tracked text file names a source paper by its input file name, calls a paper "seed 00N",
  or points at the design notes or the shared folder beside the repository: files a clone does not hold.
* A citation of a page's section in the code -- ``README "Commands"``,
  ``docs/explanation/stc-robot.md, "Red lights as landmarks"`` -- names a heading of that page
  or the bold lead of one of its paragraphs (the explanation pages' sections); a quotation of a
  page -- ``docs/explanation/stc-geometry.md: "a few centimetres from the edge line"`` -- is in
  that page; a ``docs/...md`` path the code names exists.
* A link with an anchor, ``page.md#anchor`` in the code or ``[text](page.md#anchor)`` in any
  Markdown file, lands on a heading of that page (the anchors mkdocs' ``toc`` makes).

Plain file reads and regular expressions: well under a second.
"""

from __future__ import annotations

import re
import subprocess
import unicodedata
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: the suffixes of the text files scanned for names a clone cannot open
TEXT_SUFFIXES = {".py", ".md", ".yml", ".yaml", ".toml", ".json", ".txt", ".cfg", ".ini"}
#: folders never scanned when the tree is walked instead of asking git (not part of a clone)
SKIP_DIRS = {".venv", ".git", "site", "build", "dist", "node_modules", "__pycache__", ".pytest_cache", "out"}

#: what a citation must never be, with what each means (the patterns do not match their own text)
FORBIDDEN = {
    "the input file name of a source paper (cite it by title and authors)": re.compile(r"\b00[0-3]_[0-9a-f]{16}\b"),
    'a source paper called a "seed" (say paper; seed means a random seed)': re.compile(r"\b[Ss]eed 00[0-3]\b"),
    "the design notes, a file outside the repository (cite the docs page that holds it)": re.compile(r"\bDESIGN\.md\b"),
    "a path outside the repository": re.compile(r"\.\./shared\b"),
}

#: ``PATH, "Section"`` (or ``README "Section"``) cites a section; ``PATH: "text"`` quotes the page
_PATH = r"(?P<path>(?:[\w.-]+/)*(?:[\w.-]+\.md|README))"
CITATION = re.compile(_PATH + r"""(?P<sep>,\s+|:\s+|\s+)(?:"(?P<d>[^"]{1,160})"|'(?P<s>[^']{1,160})')""")
ANCHOR = re.compile(r"(?P<path>(?:[\w.-]+/)*[\w.-]+\.md)#(?P<anchor>[\w-]+)")
DOCS_PAGE = re.compile(r"(?<![\w./-])(?P<path>docs/(?:[\w.-]+/)*[\w.-]+\.md)\b")
MD_LINK = re.compile(r"\]\((?P<target>[^)\s]+?)(?:\s+\"[^\"]*\")?\)")
HEADING = re.compile(r"^ {0,3}#{1,6}\s+(?P<text>.*?)\s*#*\s*$")
BOLD_LEAD = re.compile(r"^ {0,3}(?:[-*+]\s+|\d+\.\s+)?\*\*(?P<text>[^*]+?)\*\*")
FENCE = re.compile(r"^ {0,3}(```|~~~)")


def tracked_files() -> list[Path]:
    """The repository's tracked text files (git's list; without git, the tree less build folders)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True, timeout=30).stdout
        paths = [ROOT / p for p in out.decode().split("\0") if p]
    except (OSError, subprocess.SubprocessError):
        paths = [p for p in ROOT.rglob("*") if not SKIP_DIRS.intersection(p.relative_to(ROOT).parts)]
    return sorted(p for p in paths if p.suffix in TEXT_SUFFIXES and p.is_file())


def plain(text: str) -> str:
    """Markdown inline text as read: link texts without their targets, no code or emphasis marks."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)
    return text.replace("`", "").replace("**", "").replace("*", "")


def slugify(text: str, used: set[str]) -> str:
    """The anchor Python-Markdown's ``toc`` gives a heading (mkdocs' default), unique in its page."""
    value = unicodedata.normalize("NFKD", plain(text)).encode("ascii", "ignore").decode("ascii")
    value = re.sub(r"[-\s]+", "-", re.sub(r"[^\w\s-]", "", value).strip().lower())
    slug = value
    while slug in used:
        m = re.match(r"^(.*)_([0-9]+)$", slug)
        slug = f"{m.group(1)}_{int(m.group(2)) + 1}" if m else f"{slug}_1"
    used.add(slug)
    return slug


def words(text: str) -> str:
    """Text compared as words: plain, one space between words, case and end punctuation ignored."""
    return re.sub(r"\s+", " ", plain(text)).strip().rstrip(".:").casefold()


@cache
def page(path: Path) -> tuple[tuple[str, ...], frozenset[str], str]:
    """A Markdown page's section titles (headings, then bold paragraph leads), its anchors and its
    text as words; code blocks hold no sections."""
    titles, leads, used, body, fenced = [], [], set(), [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        if FENCE.match(line):
            fenced = not fenced
            continue
        if fenced:
            continue
        body.append(line)
        if m := HEADING.match(line):
            titles.append(words(m["text"]))
            slugify(m["text"], used)
        elif m := BOLD_LEAD.match(line):
            leads.append(words(m["text"]))
    return tuple(titles + leads), frozenset(used), words(" ".join(body))


def has_section(path: Path, title: str) -> bool:
    """``title`` is a section of the page: a heading or bold lead equal to it or starting with it."""
    want = words(title)
    return any(t == want or (t.startswith(want) and not t[len(want)].isalnum()) for t in page(path)[0])


def quotes(path: Path, quote: str) -> bool:
    """Every part of ``quote`` (split at its "..." elisions) is in the page's text."""
    text = page(path)[2]
    return all(words(part) in text for part in re.split(r"\.\.\.|…", quote) if part.strip())


def joined(text: str) -> str:
    """Source text with its lines joined (comment marks dropped), so a citation may span lines."""
    return re.sub(r"[ \t]*\n[ \t]*(?:#:?[ \t]?)?", " ", text)


def resolve(path: str, base: Path = ROOT) -> Path:
    """A cited page: ``README`` is the top-level README.md; other paths are relative to ``base``."""
    return base / (path + ".md" if path.endswith("README") else path)


def citation_problems(name: str, source: str) -> list[str]:
    """What is wrong with the page citations of one Python file's text."""
    if ".md" not in source and "README" not in source:
        return []
    problems, text = [], joined(source)
    for m in CITATION.finditer(text):
        cited, quote = resolve(m["path"]), m["d"] or m["s"]
        if not cited.is_file():
            if m["path"].startswith("docs/") or m["path"].endswith(("README", "README.md")):
                problems.append(f"{name}: cites {m['path']}, which does not exist")
            continue  # an output the code writes (summary.md, compare.md), not a page of the repository
        if m["sep"].startswith(":"):
            if not quotes(cited, quote):
                problems.append(f'{name}: quotes {m["path"]}: "{quote}", which that page does not say')
        elif not has_section(cited, quote):
            problems.append(f'{name}: cites {m["path"]} "{quote}", which is no heading or bold lead of it')
    for m in ANCHOR.finditer(text):
        cited = resolve(m["path"])
        if cited.is_file() and m["anchor"] not in page(cited)[1]:
            problems.append(f"{name}: links {m['path']}#{m['anchor']}, an anchor that page does not have")
    for m in DOCS_PAGE.finditer(text):
        if not resolve(m["path"]).is_file():
            problems.append(f"{name}: names {m['path']}, which does not exist")
    return problems


def link_problems(path: Path) -> list[str]:
    """Links of one Markdown file to an anchor that its target page does not have."""
    problems, fenced = [], False
    for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if FENCE.match(line):
            fenced = not fenced
        if fenced:
            continue
        for m in MD_LINK.finditer(line):
            target, _, anchor = m["target"].partition("#")
            if not anchor or re.match(r"^[a-z]+:", target) or (target and not target.endswith(".md")):
                continue
            cited = (path.parent / target).resolve() if target else path
            if not cited.is_file():
                continue  # a missing page is mkdocs' to report (docs/) or outside the site
            if anchor not in page(cited)[1]:
                problems.append(f"{path.relative_to(ROOT)}:{n}: links {m['target']}, an anchor that page does not have")
    return problems


def test_no_file_names_a_source_a_clone_does_not_hold():
    problems = []
    for path in tracked_files():
        if path == Path(__file__).resolve():
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            problems += [f"{path.relative_to(ROOT)}:{n}: {why}" for why, rx in FORBIDDEN.items() if rx.search(line)]
    assert not problems, "\n".join(problems)


def test_cited_sections_quotes_and_pages_exist():
    problems = []
    for path in tracked_files():
        if path.suffix == ".py" and path != Path(__file__).resolve():
            problems += citation_problems(str(path.relative_to(ROOT)), path.read_text(encoding="utf-8"))
    assert not problems, "\n".join(problems)


def test_markdown_anchor_links_land_on_a_heading():
    problems = [p for path in tracked_files() if path.suffix == ".md" for p in link_problems(path)]
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------- the checks catch what they should


def test_forbidden_names_are_caught():
    design, shared, paper = "DESIGN" + ".md", ".." + "/shared/x", "003" + "_01c9be04038c8c46.txt"
    for text in (f"see {paper} sec. 4", f"(seed {'00' + '3'}, Angle Detection)", f"the table of {design}", shared):
        assert any(rx.search(text) for rx in FORBIDDEN.values()), text
    for text in ("seed 532", "--seeds 0-4", "1_000_000", "docs/explanation/stc-geometry.md"):
        assert not any(rx.search(text) for rx in FORBIDDEN.values()), text


def test_a_section_cited_that_the_page_lacks_is_caught():
    ok = 'x = 1  # why: README "Commands";\n#: and docs/explanation/stc-robot.md, "Red lights\n#: as landmarks"'
    assert citation_problems("ok.py", ok) == []
    gone = '"""Measured (README "Drift is no longer where it stops")."""'
    assert citation_problems("gone.py", gone) == [
        'gone.py: cites README "Drift is no longer where it stops", which is no heading or bold lead of it'
    ]
    misquoted = '# docs/explanation/stc-geometry.md: "a few metres from the edge line"'
    assert len(citation_problems("q.py", misquoted)) == 1
    quoted = '# docs/explanation/stc-geometry.md: "in the entry frame ... it stands in the lower-right sub-cell"'
    assert citation_problems("q.py", quoted) == []
    assert citation_problems("p.py", "# see docs/explanation/no-such-page.md") == [
        "p.py: names docs/explanation/no-such-page.md, which does not exist"
    ]
    assert citation_problems("o.py", 'write("summary.md", "text")  # an output, not a page') == []


def test_anchors_are_mkdocs_anchors():
    assert citation_problems("a.py", "# docs/explanation/stc-geometry.md#marks-and-the-five-boxes") == []
    assert len(citation_problems("a.py", "# docs/explanation/stc-geometry.md#the-five-boxes")) == 1
    used: set[str] = set()
    assert slugify("Buffon's needle (Girgin & Şahin)", used) == "buffons-needle-girgin-sahin"
    assert slugify("Profiles from other tools (`calibrate import`; `lens_*.py`)", used) == (
        "profiles-from-other-tools-calibrate-import-lens_py"
    )
    assert [slugify("Speed", used), slugify("Speed", used)] == ["speed", "speed_1"]
