"""Every object the API reference renders has a numpy-style docstring with the sections it needs.

``docs/reference/api.md`` names its objects in ``::: dotted.name`` entries (mkdocstrings, with
``docstring_style: numpy``), some with a ``members`` list. ruff's pydocstyle rules hold the form
of those docstrings (a one-line summary, a blank line, the imperative mood) in the modules that
define them; what ruff does not check under the numpy convention is that the sections are there.
This test does: a function or method that takes parameters documents each of them under
``Parameters``, one that returns something has ``Returns`` (or ``Yields``), and a class whose
constructor takes parameters documents each of them under ``Parameters`` or ``Attributes``. It
also checks that ruff's docstring rules cover every module that defines such an object, so that
a new entry on the page cannot slip past them.
"""

from __future__ import annotations

import enum
import importlib
import inspect
import re
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
API_PAGE = ROOT / "docs" / "reference" / "api.md"

#: a numpy section header: its name on one line, dashes under it
SECTION = re.compile(r"^(\w[\w ]*)\n-{3,}\s*$", re.MULTILINE)


def api_entries() -> list[tuple[str, dict]]:
    """The ``::: name`` entries of the API page with their options (an empty dict if none)."""
    lines = API_PAGE.read_text(encoding="utf-8").splitlines()
    entries = []
    for i, line in enumerate(lines):
        if not line.startswith("::: "):
            continue
        block = []
        for follow in lines[i + 1 :]:
            if not follow.startswith("    "):
                break
            block.append(follow[4:])
        options = (yaml.safe_load("\n".join(block)) or {}).get("options", {}) if block else {}
        entries.append((line[4:].strip(), options))
    return entries


def resolve(dotted: str):
    """The object a dotted name points at: the longest importable module prefix, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            obj = getattr(obj, name)
        return obj
    raise ImportError(dotted)


def rendered_objects() -> list[tuple[str, object]]:
    """Every function, class and method the page renders, with its dotted name."""
    found = []
    for dotted, options in api_entries():
        obj = resolve(dotted)
        members = options.get("members")
        if inspect.ismodule(obj):
            for name in members if members is not None else obj.__all__:
                found.append((f"{dotted}.{name}", getattr(obj, name)))
            continue
        found.append((dotted, obj))
        if inspect.isclass(obj):
            names = members if members is not None else [n for n in vars(obj) if not n.startswith("_")]
            for name in names:
                raw = inspect.getattr_static(obj, name)
                if isinstance(raw, (staticmethod, classmethod)) or inspect.isfunction(raw):
                    found.append((f"{dotted}.{name}", getattr(obj, name)))
    return found


RENDERED = rendered_objects()


def sections(doc: str) -> dict[str, str]:
    """The docstring's numpy sections: header -> body (the text up to the next header)."""
    heads = list(SECTION.finditer(doc))
    return {
        m.group(1).strip(): doc[m.end() : heads[k + 1].start() if k + 1 < len(heads) else len(doc)]
        for k, m in enumerate(heads)
    }


def documented_names(body: str) -> set[str]:
    """The names a Parameters or Attributes section documents: its unindented entry lines,
    ``name : type`` or ``a, b : type`` (stars of ``*args`` dropped)."""
    names = set()
    for line in body.splitlines():
        if not line or line[0].isspace():
            continue
        for name in line.split(" : ")[0].split(","):
            names.add(name.strip().lstrip("*"))
    return names


def parameters(obj) -> list[str]:
    """The parameters a caller passes (not ``self``/``cls``, which the bound method drops).

    An enumeration's are its members: nobody calls it with a value it does not name. A protocol
    (a structural type) is never called: it has none.
    """
    if inspect.isclass(obj) and issubclass(obj, enum.Enum):
        return list(obj.__members__)
    if inspect.isclass(obj) and getattr(obj, "_is_protocol", False):
        return []
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return []
    return [p for p in sig.parameters if p not in ("self", "cls")]


def returns_something(obj) -> bool:
    annotation = inspect.signature(obj).return_annotation
    return annotation not in (inspect.Signature.empty, None, "None")


def test_the_page_renders_objects():
    assert len(RENDERED) > 50  # the page parsed: its entries and their members


@pytest.mark.parametrize(("dotted", "obj"), RENDERED, ids=[d for d, _ in RENDERED])
def test_rendered_object_documents_its_parameters(dotted, obj):
    doc = inspect.getdoc(obj)
    assert doc and not doc.startswith(f"{getattr(obj, '__name__', '')}("), f"{dotted} has no docstring"
    found = sections(doc)
    params = parameters(obj)
    if inspect.isclass(obj):
        documented = documented_names(found.get("Parameters", "")) | documented_names(found.get("Attributes", ""))
        if params:
            assert "Parameters" in found or "Attributes" in found, f"{dotted} takes {params}: no Parameters"
    else:
        documented = documented_names(found.get("Parameters", ""))
        if params:
            assert "Parameters" in found, f"{dotted} takes {params}: no Parameters section"
        if returns_something(obj):
            assert "Returns" in found or "Yields" in found, f"{dotted} returns a value: no Returns section"
    missing = [p for p in params if p not in documented]
    assert not missing, f"{dotted}: parameters not documented: {missing}"


def test_ruff_docstring_rules_cover_the_rendered_modules():
    """The modules defining the page's objects are the ones pyproject.toml holds to ruff's D rules
    (a negated per-file-ignores glob: every other file ignores them)."""
    lint = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["ruff"]["lint"]
    assert "D" in lint.get("select", []) + lint.get("extend-select", [])
    [held] = [glob for glob, rules in lint["per-file-ignores"].items() if glob.startswith("!{") and rules == ["D"]]
    covered = set(held[2:-1].split(","))
    files = set()
    for _, obj in RENDERED:
        source = Path(inspect.getsourcefile(inspect.unwrap(obj))).resolve()
        files.add(source.relative_to(ROOT).as_posix())
    assert files <= covered, f"not held by ruff's docstring rules: {sorted(files - covered)}"
