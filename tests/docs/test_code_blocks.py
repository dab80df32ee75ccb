"""Every Python and shell code block of the README and the tutorials runs, as written or at a
small size, so none can rot.

A small collector of our own rather than mktestdocs or pytest-markdown-docs: a tutorial is a
*sequence* (a shell block renders frames that the next Python block reads; the Python blocks of
one page share their names), its commands must run in a scratch folder with the repository's
data beside them, and long commands need an explicit, checked table of smaller sizes. mktestdocs
runs Python blocks (and bash ones one by one) without shared state or a working folder;
pytest-markdown-docs runs Python only.

How a page runs: one test per page; a fresh temporary folder is the working directory, holding
symbolic links to the repository's ``datasets/``, ``calibration/`` and ``docs/`` (read only:
commands always write with ``--out`` into the scratch folder); the page's ``bash`` / ``sh`` /
``shell`` / ``console`` blocks run with ``bash -euo pipefail`` and this venv's ``bin/`` first on
PATH; its ``python`` blocks run in one namespace, in order. Blocks in other languages are not
run: ``text`` holds a command's output, or commands that run until stopped (a Dask scheduler and
its workers) or install packages. A block's text goes through :data:`SMALLER` first.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: the pages whose code blocks must run: the README, every tutorial and how-to guide, the API page
PAGES = [
    ROOT / "README.md",
    *sorted((ROOT / "docs" / "tutorials").glob("*.md")),
    *sorted((ROOT / "docs" / "how-to").glob("*.md")),
    ROOT / "docs" / "reference" / "api.md",
]
SHELL = {"bash", "sh", "shell", "console"}
#: what the scratch folder links to, so that documented paths such as datasets/peer_data/... work
LINKED = ("datasets", "calibration", "docs")

#: The substitution table: (text in a page, what the test runs instead, why). Each entry must be
#: used by some block (a test checks it), so the table cannot go stale. Sizes shrink only; the
#: commands, options and outputs stay the documented ones.
SMALLER: list[tuple[str, str, str]] = [
    ("make demo", "stcvision demo --out out --force", "the Makefile target's own command (make would reinstall)"),
    ("make test", "true", "the suite itself: running it from inside the suite would recurse"),
    ("rerun out/demo.rrd", "rerun rrd verify out/demo.rrd", "the viewer needs a display; the file must load"),
    ("rerun cover.rrd", "rerun rrd verify cover.rrd", "the viewer needs a display; the file must load"),
    (
        "buffon reproduce --out buffon_paper --trials 100",
        "buffon reproduce --out buffon_paper --trials 1 --online-trials 0 --workers 1",
        "Buffon reproduce: 1 trial per nest, no online-rule sets, in-process",
    ),
    ("--trials 100", "--trials 2", "Buffon: 2 trials per nest instead of the paper's 100"),
    ("--seeds 8", "--seeds 1 --max-steps 5 --workers 1", "TASTI 2 reproduce: one seed, patterns cut at 5 steps"),
    ("--board 8x8", "--board 2x2", "STC: a 2x2-cell board instead of 8x8"),
    ("--sizes 4,6 --runs 3", "--sizes 2 --runs 1 --workers 1", "STC sweep: one 2x2 board per camera, in-process"),
    ("--boards 500 --pairs 1000000", "--boards 2 --pairs 2000", "the C check: 2 boards, 2,000 pairs"),
    ("--boards 20 --pairs 100000", "--boards 2 --pairs 5000", "the C check's short form: 2 boards, 5,000 pairs"),
]


def code_blocks(path: Path) -> list[tuple[int, str, str]]:
    """(line, language, text) of every fenced block of ``path`` whose language is shell or Python."""
    blocks, lang, start, lines = [], None, 0, []
    fence = re.compile(r"^(\s*)```\s*([\w+-]*)")
    for i, line in enumerate(path.read_text().splitlines(), 1):
        m = fence.match(line)
        if lang is None and m:
            lang, start, lines = (m.group(2) or "text").lower(), i, []
        elif lang is not None and line.strip() == "```":
            if lang in SHELL or lang == "python":
                blocks.append((start, lang, "\n".join(lines) + "\n"))
            lang = None
        elif lang is not None:
            lines.append(line)
    return blocks


def smaller(text: str) -> str:
    for old, new, _ in SMALLER:
        text = text.replace(old, new)
    return text


def _scratch(tmp_path: Path) -> Path:
    for name in LINKED:
        (tmp_path / name).symlink_to(ROOT / name)
    return tmp_path


def _env() -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = str(ROOT)
    env.pop("HYPOTHESIS_PROFILE", None)
    return env


def run_page(path: Path, cwd: Path) -> None:
    namespace: dict = {"__name__": "__docs__"}
    for line, lang, text in code_blocks(path):
        code = smaller(text)
        where = f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path.name}:{line}"
        if lang in SHELL:
            code = "\n".join(ln[2:] if ln.startswith("$ ") else ln for ln in code.splitlines())
            done = subprocess.run(
                ["bash", "-euo", "pipefail", "-c", code], cwd=cwd, env=_env(), capture_output=True, text=True
            )
            output = done.stdout[-2000:] + done.stderr[-3000:]
            assert done.returncode == 0, f"{where}: exit {done.returncode}\n{code}\n{output}"
        else:
            old = os.getcwd()
            os.chdir(cwd)
            try:
                exec(compile(code, where, "exec"), namespace)
            except Exception as exc:  # name the block: a page has many
                raise AssertionError(f"{where}: {type(exc).__name__}: {exc}\n{code}") from exc
            finally:
                os.chdir(old)


@pytest.mark.slow  # each page runs its commands, seconds each
@pytest.mark.parametrize("page", PAGES, ids=[p.name for p in PAGES])
def test_every_code_block_runs(page, tmp_path):
    assert code_blocks(page), f"{page.name} has no code block to run"
    run_page(page, _scratch(tmp_path))


def test_every_substitution_is_used():
    texts = [text for page in PAGES for _, _, text in code_blocks(page)]
    unused = [old for old, _, _ in SMALLER if not any(old in t for t in texts)]
    assert not unused, f"substitutions no block uses (remove them): {unused}"


def test_the_collector_finds_blocks_and_skips_output(tmp_path):
    md = tmp_path / "page.md"
    md.write_text("x\n```bash\necho a\n```\n```text\nnot code\n```\n```python\nx = 1\n```\n")
    assert [(lang, text) for _, lang, text in code_blocks(md)] == [("bash", "echo a\n"), ("python", "x = 1\n")]


def test_a_failing_block_fails_the_page(tmp_path):
    md = tmp_path / "page.md"
    md.write_text("```bash\ntrue\n```\n```bash\nfalse\n```\n```python\nraise SystemExit\n```\n")
    with pytest.raises(AssertionError, match=r"page.md:4: exit 1"):
        run_page(md, tmp_path)
    md.write_text("```python\nx = 1\n```\n```python\nassert x == 2\n```\n")
    with pytest.raises(AssertionError, match=r"page.md:4: AssertionError"):
        run_page(md, tmp_path)
